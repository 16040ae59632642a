"""The archive: settings (`settings`), the encoder (`writer`), the reader (`reader`), old
formats' decoders (`legacy`) and the checks on meta every reader runs (`meta`).

    compress(inputs, "db.mcz", Settings(error_cm=1.0))
    with Archive("db.mcz") as archive: archive.decode(0)   # a formats.amc.Motion
"""

from mocapzip.archive.reader import Archive, decompress, info
from mocapzip.archive.settings import DEFAULT_ERROR_CM, Settings, SettingsError

__all__ = ["DEFAULT_CACHE_MB", "DEFAULT_ERROR_CM", "Archive", "Settings", "SettingsError", "compress", "decompress",
           "info"]


def __getattr__(name: str):
    """The encoder's names, loaded on first use: decompress, info and test do not need its modules
    (37 ms of imports)."""
    if name in ("DEFAULT_CACHE_MB", "compress"):
        from mocapzip.archive import writer

        return getattr(writer, name)
    raise AttributeError(f"module 'mocapzip.archive' has no attribute {name!r}")
