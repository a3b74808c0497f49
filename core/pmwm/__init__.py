"""pmwm: blind, robust 3D mesh watermarking carried by a progressive mesh.

See docs/api.md for the public API. The package never imports bpy.
"""

from .errors import KeyFileError, MeshError, OutputExistsError, PayloadError, PmwmError, PMFormatError

__version__ = "0.1.0"

__all__ = [
    "PmwmError",
    "MeshError",
    "PMFormatError",
    "KeyFileError",
    "PayloadError",
    "OutputExistsError",
]
