"""mocapzip: compress motion-capture databases (Acclaim ASF/AMC, BVH) into one small .mcz archive.

    import mocapzip
    with mocapzip.open("db.mcz") as archive:
        clip = archive["07/07_01.amc"]   # decodes this clip only
        clip.positions()                 # (frames, joints, 3) in cm

The API (docs/api.md) lives in `mocapzip.api`; its names are loaded on first use, so that
`import mocapzip` (and `mcz --help`) stays fast.

The packages, in pipeline order (docs/architecture.md): `inputs` (which files are clips),
`motion` (skeletons, kinematics, metrics), `representations` (what the codec compresses),
`classes` (which clips share a basis), `codec` (the stages), `ratecontrol` (the error budget
spent), `archive` (compress and decompress), `legacy` (old formats, decode only), and `bench`; `formats` (the file formats) and `cli`
(the command line) install from formats/ and cli/. Beside them: `stages` (the one registry of
stages), `convert` (`mcz convert`), `plots` (`mcz plot` and `mcz view`, with the `plot` extra), `parallel` and `cluster` (the work over `-j` processes or a
Dask cluster), `limits` (what every reader checks), `defaults` (values the CLI and API share
without NumPy), `schema` (the JSON Schema pieces meta and the input formats share) and
`progress` (progress bars).
"""

import os as _os

__version__ = "0.1.0"
__all__ = ["ArchiveError", "Bvh", "Clip", "ClipFidelity", "MocapArchive", "MocapFormatError", "SettingsError",
           "ShellError", "__version__", "append", "bvh_joint_positions", "bvh_point_names", "compress",
           "decompress", "joint_positions", "read_amc", "read_asf", "read_bvh", "remove", "write_amc", "write_asf",
           "write_bvh"]
_API = {*__all__, "open"} - {"__version__"}  # `open` is left out of __all__: a star import keeps the built-in


def __getattr__(name: str):
    if name in _API:
        from mocapzip import api

        return getattr(api, name)
    raise AttributeError(f"module 'mocapzip' has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted({*globals(), *_API})

# Run from a source checkout. formats/ and cli/ live beside this directory, not inside it;
# setuptools maps them to mocapzip.formats / mocapzip.cli only when installing (package-dir in
# pyproject.toml; an editable install maps them to these same files). But `python -m pytest` or
# `python -c ...` started in the repository root puts the root first on sys.path, so this in-tree
# package is imported even when a wheel is installed, and it would have no formats/cli. So when
# this directory has no formats/ and it sits in a checkout (pyproject.toml and formats/ beside
# it), also look for subpackages in the checkout root: mocapzip.formats is then formats/ of the
# SAME checkout, never another copy. Inert in an installed wheel (formats/ is inside the package).
_here = _os.path.dirname(_os.path.abspath(__file__))
_root = _os.path.dirname(_here)
if (not _os.path.isdir(_os.path.join(_here, "formats"))
        and _os.path.isfile(_os.path.join(_root, "pyproject.toml"))
        and _os.path.isfile(_os.path.join(_root, "formats", "__init__.py"))):
    __path__.append(_root)  # after this directory: mocapzip/*.py always win
del _os, _here, _root
