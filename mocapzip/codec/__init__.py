"""Codec stages of mocapzip and a registry that rebuilds them from JSON configs.

Each stage class has a `codec_id`, `get_config() -> dict` (JSON-safe, with
the id under "id") and a `from_config(dict)` classmethod, as in numcodecs.
A container stores the configs, and `get_stage(config)` turns one back into
a working stage, so a file describes how it was encoded.

Stages with parameters: `DctTransform`, `DwtTransform`, `IdentityTransform`
(temporal.py) and `UniformQuantiser` (quantise.py).  The modules pca,
entropy and lossless hold data-driven or fixed steps and are used directly.
"""

from mocapzip.codec.quantise import UniformQuantiser
from mocapzip.codec.temporal import DctTransform, DwtTransform, IdentityTransform

__all__ = ["TRANSFORMS", "get_stage", "register_stage"]

_REGISTRY = {}


def register_stage(cls):
    """Make `get_stage` know a stage class by its `codec_id` (usable as a decorator)."""
    existing = _REGISTRY.get(cls.codec_id)
    if existing is not None and existing is not cls:
        raise ValueError(f"stage id {cls.codec_id!r} is already registered to {existing.__name__}")
    _REGISTRY[cls.codec_id] = cls
    return cls


def get_stage(config: dict):
    """Build a stage from its config, e.g. {"id": "dwt", "wavelet": "db4", "level": None}."""
    if "id" not in config:
        raise ValueError(f"stage config has no 'id': {config!r}")
    try:
        cls = _REGISTRY[config["id"]]
    except KeyError:
        known = ", ".join(sorted(_REGISTRY))
        raise ValueError(f"unknown stage id {config['id']!r} (known: {known})") from None
    return cls.from_config(config)


for _stage in (DctTransform, DwtTransform, IdentityTransform, UniformQuantiser):
    register_stage(_stage)

TRANSFORMS = tuple(stage.codec_id for stage in (DctTransform, DwtTransform, IdentityTransform))  # temporal, by id
