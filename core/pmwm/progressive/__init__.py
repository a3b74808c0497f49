"""Progressive meshes: a base mesh refined by vertex-split records, built by batched half-edge collapses.

The package's rooms:

- ``mesh``: the ``ProgressiveMesh`` type, ``with_positions`` and ``base_vertex_count``;
- ``records``: what a vertex-split record holds (flags, mask bits) and the face-corner arithmetic;
- ``decode``: the decoder (``ProgressiveMesh.decode`` calls it);
- ``build``: the encoder, ``build_progressive_mesh``, with its ``quadrics``, its state between passes
  (``state``), the choice of a pass's collapses (``select``) and their application (``collapse``);
- ``fileformat``: the .pmwm file.
"""

from .build import build_progressive_mesh
from .fileformat import HEADER, MAGIC, VERSION, from_bytes, read_pm, record_size, to_bytes, write_pm
from .mesh import ProgressiveMesh, base_vertex_count, with_positions
from .records import ENDS_SHIFT, FLAG_SECOND, FLAG_SINGLE, MAX_FAN, NO_END

__all__ = [
    "ProgressiveMesh",
    "build_progressive_mesh",
    "with_positions",
    "base_vertex_count",
    "to_bytes",
    "from_bytes",
    "read_pm",
    "write_pm",
    "record_size",
    "MAGIC",
    "VERSION",
    "HEADER",
    "ENDS_SHIFT",
    "FLAG_SECOND",
    "FLAG_SINGLE",
    "MAX_FAN",
    "NO_END",
]
