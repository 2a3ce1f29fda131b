"""The finite-element discretisation: the elements (element.py), global matrices and
vectors (assembly.py), rigid-body motions (rigid.py), the contact frame and the contact
set, the discrete problem of a scene (discretisation.py) and its admissibility check.
`contact.fem` names the elements' and the assembly's functions directly (as DOLFINx's
`dolfinx.fem` does)."""
from contact.fem.element import (ELEMENTS, CHUNK, chunk, lame, q2_shape,
                                 NODES, QUADRATIC, PRESSURES, geometry, element_stiffness,
                                 element_stiffness_shapes, pressure_basis,
                                 projected_divergence, element_volume_weights, face_weights,
                                 q2_face_weights, nodal_face_weights)
from contact.fem.assembly import (PATTERN_CHUNK, create_matrix, assemble_stiffness,
                                  assemble_diagonal, assemble_divergence, pressure_parts,
                                  local_to_global,
                                  load_vector, global_coordinates, dirichlet_rows,
                                  dirichlet_values, face_normals, eliminate_dirichlet,
                                  configure_elasticity, is_blocked, set_spd)
from contact.fem.rows import eliminated_difference, rows_of
from contact.fem.rigid import (RIGID_MODES, rigid_modes, free_rigid_modes, tangential_modes,
                               free_translations, load_lifts_off)

__all__ = ["ELEMENTS", "CHUNK", "chunk", "lame", "q2_shape",
           "NODES", "QUADRATIC", "PRESSURES", "geometry", "element_stiffness",
           "element_stiffness_shapes", "pressure_basis", "projected_divergence",
           "element_volume_weights", "face_weights", "q2_face_weights",
           "nodal_face_weights", "PATTERN_CHUNK", "create_matrix", "assemble_stiffness",
           "assemble_diagonal", "assemble_divergence", "pressure_parts", "local_to_global",
           "load_vector",
           "global_coordinates", "dirichlet_rows", "dirichlet_values", "face_normals",
           "RIGID_MODES", "rigid_modes", "free_rigid_modes", "tangential_modes",
           "free_translations", "load_lifts_off", "eliminate_dirichlet",
           "eliminated_difference", "rows_of",
           "configure_elasticity", "is_blocked", "set_spd"]
