"""Exception types raised by pmwm.

Every error a user can cause (bad file, bad key, bad argument) is a subclass of
:class:`PmwmError` whose message is one line naming the problem and the way out.
The command line prints it and exits with code 2; the Blender add-on turns it into
``self.report({'ERROR'}, ...)``. Anything else escaping pmwm is a bug.
"""

from __future__ import annotations


class PmwmError(Exception):
    """Base class of all user-facing pmwm errors (one-line message)."""


class MeshError(PmwmError):
    """The mesh cannot be read, written or watermarked as given."""


class PMFormatError(PmwmError):
    """A progressive-mesh file is truncated, corrupted or of an unknown version."""


class KeyFileError(PmwmError):
    """A key file is missing, unreadable, of another version, or inconsistent."""


class PayloadError(PmwmError):
    """The payload (text or bits) is invalid or does not fit the mesh."""


class OutputExistsError(PmwmError):
    """An output file exists and overwriting was not allowed."""


class ParameterError(PmwmError, ValueError):
    """A parameter (attack strength, fraction, method name...) is out of its range."""
