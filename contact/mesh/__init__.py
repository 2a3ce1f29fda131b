"""Meshes: hexahedral DMPlex meshes (plex.py: boxes, files, METIS distribution,
connectivity, boundary parts), the levels of a scene (hierarchy.py), gmsh input
(gmshio.py), partition-independent orders (canonical.py) and the coarse-to-fine transfer
(transfer.py). `contact.mesh` names plex.py's functions directly."""
from contact.mesh.plex import (HEX_REF, HEX_FACES, Q2_REF, Q2_ROLE, Q1_ROLE, MeshError,
                               create_box_mesh, read_mesh_file, cross3, CHECK_CHUNK,
                               check_cells, distribute, cell_vertices, boundary_faces,
                               displacement_section, label_parts, labelled_faces,
                               labelled_cell_faces, rotate_coordinates, turned, lattice,
                               lattice_index)

__all__ = ["HEX_REF", "HEX_FACES", "Q2_REF", "Q2_ROLE", "Q1_ROLE", "MeshError", "create_box_mesh",
           "read_mesh_file", "cross3", "CHECK_CHUNK", "check_cells", "distribute", "cell_vertices",
           "boundary_faces", "displacement_section", "label_parts", "labelled_faces",
           "labelled_cell_faces", "rotate_coordinates", "turned", "lattice", "lattice_index"]
