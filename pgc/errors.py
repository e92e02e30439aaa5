"""Exception types. Every message names the file or field at fault and how to fix it."""


class PGCError(Exception):
    """Base class of all PGC errors."""


class PGCDataError(PGCError, ValueError):
    """Input data is malformed (a file, a field, an array shape)."""


class PGCConfigError(PGCError, ValueError):
    """A run configuration is invalid (unknown role, implementation or option)."""


class PGCPluginError(PGCError, RuntimeError):
    """A plugin cannot be used (missing dependency, import failure, bad registration)."""


class PGCLockError(PGCError, RuntimeError):
    """An output folder is being written by another live process."""
