"""The archive: settings (`settings`), the encoder (`writer`, a recipe of the compress `passes/`),
the reader (`reader`), `mcz remove` and `mcz append` (`edit`), the checks on meta every reader runs (`meta`), the `skeletons` stream
(`skeletons`) and the zstd dictionaries and skeleton means of the format (`dictionaries/`). Old
formats' differences are `mocapzip.legacy`'s.

    compress(inputs, "db.mcz", Settings(error_cm=1.0))
    with Archive("db.mcz") as archive: archive.decode(0)   # a formats.amc.Motion
"""

from mocapzip.archive.reader import Archive, decompress, info
from mocapzip.archive.settings import DEFAULT_ERROR_CM, Settings, SettingsError
from mocapzip.defaults import DEFAULT_CACHE_MB

__all__ = ["DEFAULT_CACHE_MB", "DEFAULT_ERROR_CM", "Archive", "Settings", "SettingsError", "compress", "decompress",
           "info"]


def __getattr__(name: str):
    """The encoder, loaded on first use: decompress, info and test do not need its modules (37 ms
    of imports)."""
    if name == "compress":
        from mocapzip.archive.writer import compress

        return compress
    raise AttributeError(f"module 'mocapzip.archive' has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted({*globals(), "compress"})
