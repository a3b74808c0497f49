"""pmwm: blind, robust 3D mesh watermarking carried by a progressive mesh.

See docs/api.md for the public API and docs/modules.md for the module map. The package never
imports bpy.
"""

__version__ = "0.1.0"

from .api import ber_per_level, embed, read_key, verify, verify_keys, verify_pm
from .base import KEY_FILE, PASS_PHRASE, EmbedOptions, EmbedResult, KeysVerdict, Verdict, VerdictDetail
from .errors import KeyFileError, MeshError, OutputExistsError, PayloadError, PmwmError, PMFormatError
from .key import WatermarkKey, write_key
from .meshio import SourceMesh, read_mesh, write_marked, write_mesh
from .progressive import read_pm, write_pm
from .progressive import ProgressiveMesh, build_progressive_mesh
from .schemes import SCHEMES

__all__ = [
    "PmwmError",
    "MeshError",
    "PMFormatError",
    "KeyFileError",
    "PayloadError",
    "OutputExistsError",
    "WatermarkKey",
    "read_key",
    "write_key",
    "SourceMesh",
    "read_mesh",
    "write_mesh",
    "write_marked",
    "ProgressiveMesh",
    "build_progressive_mesh",
    "read_pm",
    "write_pm",
    "EmbedOptions",
    "EmbedResult",
    "Verdict",
    "KeysVerdict",
    "VerdictDetail",
    "embed",
    "verify",
    "verify_keys",
    "verify_pm",
    "ber_per_level",
    "SCHEMES",
    "KEY_FILE",
    "PASS_PHRASE",
]
