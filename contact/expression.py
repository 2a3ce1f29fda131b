"""Scene expressions: a friction coefficient or an initial gap given as a formula in x, y, z.

The text is parsed (Python's `ast`, which only builds a tree) and the tree is checked
against the language below before anything is evaluated; evaluation walks the checked
tree with NumPy, one array operation per node. Nothing is passed to `eval`, so a scene
file or a command line cannot run code, whatever it contains (emptying `__builtins__` does
not make `eval` safe: attribute walks such as ().__class__.__base__ reach every module).

Why our own whitelist rather than a library: the language is a dozen constructs; the
candidates either call `eval` after a blacklist (numexpr's `validate`, CVE-2023-39631
before 2.8.5) or interpret most of Python (asteval: loops, functions, attribute access),
a larger surface to keep safe than this file.

The language (`LANGUAGE`, also in the README and in every refusal):
  numbers (floating point: 9**9**9 overflows to inf, which the checks of the values
  refuse, instead of computing a 380-million-digit integer), the variables x, y, z (the
  node's coordinates), the constants pi and e, True and False;
  + - * / // % ** and unary + -; comparisons < <= > >= == != (chains too: 0 < x < 1);
  and, or, not (elementwise, as are & | ~ on comparisons);
  the functions FUNCTIONS (NumPy's, elementwise), e.g. where(x < 1.5, 0.3, 0.0).
Cost is bounded: at most MAX_LENGTH characters and MAX_DEPTH levels of nesting, each node
one vectorised operation on the nodes' values.
"""
import ast
import math
import operator

import numpy as np

#: the longest expression accepted (characters), and the deepest nesting
MAX_LENGTH = 1000
MAX_DEPTH = 100

#: name -> (NumPy function, number of arguments)
FUNCTIONS = {"where": (np.where, 3), "abs": (np.abs, 1), "sqrt": (np.sqrt, 1),
             "minimum": (np.minimum, 2), "maximum": (np.maximum, 2),
             "sin": (np.sin, 1), "cos": (np.cos, 1), "tan": (np.tan, 1),
             "exp": (np.exp, 1), "log": (np.log, 1), "tanh": (np.tanh, 1),
             "arctan2": (np.arctan2, 2), "hypot": (np.hypot, 2)}
VARIABLES = ("x", "y", "z")
CONSTANTS = {"pi": np.pi, "e": np.e}

_BINARY = {ast.Add: operator.add, ast.Sub: operator.sub, ast.Mult: operator.mul,
           ast.Div: operator.truediv, ast.FloorDiv: operator.floordiv, ast.Mod: operator.mod,
           ast.Pow: operator.pow, ast.BitAnd: operator.and_, ast.BitOr: operator.or_}
_UNARY = {ast.UAdd: operator.pos, ast.USub: operator.neg, ast.Invert: operator.invert,
          ast.Not: np.logical_not}
_COMPARE = {ast.Lt: operator.lt, ast.LtE: operator.le, ast.Gt: operator.gt,
            ast.GtE: operator.ge, ast.Eq: operator.eq, ast.NotEq: operator.ne}
_BOOL = {ast.And: np.logical_and, ast.Or: np.logical_or}

LANGUAGE = ("numbers, x, y, z, pi, e, + - * / // % **, comparisons, and/or/not, & | ~, "
            "and the functions " + ", ".join(FUNCTIONS))

#: what a refused construct is called in the error message
_NAMES = {ast.Attribute: "attribute access", ast.Subscript: "subscript",
          ast.Lambda: "lambda", ast.ListComp: "comprehension", ast.SetComp: "comprehension",
          ast.DictComp: "comprehension", ast.GeneratorExp: "comprehension",
          ast.JoinedStr: "format string", ast.FormattedValue: "format string",
          ast.IfExp: "conditional expression (use where(c, a, b))",
          ast.NamedExpr: "assignment (:=)", ast.List: "list", ast.Tuple: "tuple",
          ast.Set: "set", ast.Dict: "dict", ast.Starred: "starred argument",
          ast.Await: "await", ast.Yield: "yield", ast.YieldFrom: "yield",
          ast.Slice: "slice"}
_OPNAMES = {ast.LShift: "<<", ast.RShift: ">>", ast.BitXor: "^", ast.MatMult: "@",
            ast.Is: "is", ast.IsNot: "is not", ast.In: "in", ast.NotIn: "not in"}


class ExpressionError(ValueError):
    """An expression outside the language, or one that cannot be evaluated."""


class Expression:
    """A checked expression in x, y, z; `values(xyz)` evaluates it at points (n, 3)."""

    def __init__(self, text):
        self.text = text
        if len(text) > MAX_LENGTH:
            raise ExpressionError(f"is {len(text)} characters long; at most {MAX_LENGTH} "
                                  "are accepted")
        try:
            tree = ast.parse(text.strip(), mode="eval")
        except SyntaxError as e:
            raise ExpressionError(f"is not a valid expression ({e.msg})") from None
        except (RecursionError, MemoryError):
            raise ExpressionError("is nested too deeply") from None
        self._tree = tree.body
        self._check(self._tree, 0)

    def __repr__(self):
        return f"Expression({self.text!r})"

    def _refuse(self, node, what):
        seg = ast.get_source_segment(self.text.strip(), node)
        if seg and len(seg) > 40:
            seg = seg[:37] + "..."
        at = f" in {seg!r}" if seg and seg != self.text.strip() else ""
        raise ExpressionError(f"uses {what}{at}, which an expression may not (allowed: "
                              f"{LANGUAGE})")

    def _bad_constant(self, node, why):
        seg = ast.get_source_segment(self.text.strip(), node)
        seg = seg if len(seg) <= 40 else seg[:37] + "..."
        raise ExpressionError(f"has a constant part {seg!r} that floating point cannot "
                              f"hold ({why})")

    def _check(self, node, depth):
        """Refuse what is outside the language; True where the subtree is a constant (its
        value is then computed once here, so 9**9**9 is refused before any mesh)."""
        const = self._check_node(node, depth)
        if const and type(node) not in (ast.Constant, ast.Name):
            with np.errstate(over="raise", divide="raise", invalid="raise"):
                try:
                    v = self._eval(node, {})
                except (FloatingPointError, ArithmeticError, ValueError, TypeError) as e:
                    what = str(e).replace("encountered in", "in") or type(e).__name__
                    self._bad_constant(node, what)
            if not np.all(np.isfinite(np.asarray(v, dtype=float))):
                self._bad_constant(node, "not finite")
        return const

    def _check_node(self, node, depth):
        if depth > MAX_DEPTH:
            raise ExpressionError(f"is nested more than {MAX_DEPTH} levels deep")
        kind = type(node)
        if kind is ast.Constant:
            v = node.value
            if isinstance(v, bool) or (isinstance(v, (int, float)) and not isinstance(v, bool)):
                if not isinstance(v, bool):
                    try:
                        ok = math.isfinite(float(v))
                    except OverflowError:
                        ok = False
                    if not ok:
                        self._bad_constant(node, "too large")
                return True
            self._refuse(node, "a string" if isinstance(v, (str, bytes)) else
                         f"the constant {v!r}")
        elif kind is ast.Name:
            if node.id not in VARIABLES and node.id not in CONSTANTS:
                self._refuse(node, f"the name '{node.id}'" + (
                    " as a value (call it: name(...))" if node.id in FUNCTIONS else ""))
            return node.id in CONSTANTS
        elif kind is ast.BinOp:
            if type(node.op) not in _BINARY:
                self._refuse(node, f"the operator {_OPNAMES.get(type(node.op), '?')}")
            return all([self._check(node.left, depth + 1),
                        self._check(node.right, depth + 1)])
        elif kind is ast.UnaryOp:
            return self._check(node.operand, depth + 1)
        elif kind is ast.BoolOp:
            return all([self._check(v, depth + 1) for v in node.values])
        elif kind is ast.Compare:
            for op in node.ops:
                if type(op) not in _COMPARE:
                    self._refuse(node, f"the comparison '{_OPNAMES.get(type(op), '?')}'")
            return all([self._check(v, depth + 1) for v in [node.left] + node.comparators])
        elif kind is ast.Call:
            f = node.func
            if type(f) is not ast.Name:
                self._check(f, depth + 1)         # names the construct (attribute, ...)
                self._refuse(node, "a call of something other than a function's name")
            if f.id not in FUNCTIONS:
                self._refuse(node, f"the function '{f.id}'")
            if node.keywords:
                self._refuse(node, "keyword arguments")
            const = all([self._check(a, depth + 1) for a in node.args])
            nargs = FUNCTIONS[f.id][1]
            if len(node.args) != nargs:
                raise ExpressionError(f"calls {f.id} with {len(node.args)} argument(s); it "
                                      f"takes {nargs}")
            return const
        else:
            self._refuse(node, _NAMES.get(kind, f"a {kind.__name__} construct"))

    def values(self, xyz):
        """The expression at the points xyz (n, 3): a float array (n,)."""
        xyz = np.asarray(xyz, dtype=float).reshape(-1, 3)
        env = dict(zip(VARIABLES, xyz.T))
        with np.errstate(all="ignore"):        # inf/nan are the caller's to report
            try:
                v = self._eval(self._tree, env)
                return np.broadcast_to(np.asarray(v, dtype=float), (xyz.shape[0],)).copy()
            except (TypeError, ValueError, ArithmeticError) as e:
                raise ExpressionError(f"cannot be evaluated: {type(e).__name__}: {e}") \
                    from None

    def _eval(self, node, env):
        kind = type(node)
        if kind is ast.Constant:
            return np.bool_(node.value) if isinstance(node.value, bool) \
                else np.float64(node.value)
        if kind is ast.Name:
            return env[node.id] if node.id in env else np.float64(CONSTANTS[node.id])
        if kind is ast.BinOp:
            return _BINARY[type(node.op)](self._eval(node.left, env),
                                          self._eval(node.right, env))
        if kind is ast.UnaryOp:
            return _UNARY[type(node.op)](self._eval(node.operand, env))
        if kind is ast.BoolOp:
            out = self._eval(node.values[0], env)
            for v in node.values[1:]:
                out = _BOOL[type(node.op)](out, self._eval(v, env))
            return out
        if kind is ast.Compare:
            left, out = self._eval(node.left, env), None
            for op, c in zip(node.ops, node.comparators):
                right = self._eval(c, env)
                r = _COMPARE[type(op)](left, right)
                out = r if out is None else np.logical_and(out, r)
                left = right
            return out
        # ast.Call (the only other node _check lets through)
        return FUNCTIONS[node.func.id][0](*(self._eval(a, env) for a in node.args))


def parse(spec):
    """A number (returned as float) or an Expression; raises ExpressionError."""
    if isinstance(spec, (int, float)) and not isinstance(spec, bool):
        return float(spec)
    if not isinstance(spec, str):
        raise ExpressionError(f"must be a number or an expression in x, y, z, got {spec!r}")
    return Expression(spec)


def values(spec, xyz):
    """spec (a number, an expression's text or an Expression) at the points xyz (n, 3)."""
    e = spec if isinstance(spec, Expression) else parse(spec)
    if isinstance(e, float):
        return np.full(np.asarray(xyz).reshape(-1, 3).shape[0], e)
    return e.values(xyz)
