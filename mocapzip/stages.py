"""The one registry of pipeline stages, as in numcodecs: each stage is rebuilt from a JSON config.

Every stage class subclasses `Stage`, names its `kind` and its `codec_id`, and is registered
with `@register`. `get_config()` gives {"id": codec_id, **parameters}; `get_stage(kind, config)`
turns it back into an equal stage. An archive's settings name every stage of its chain
(`mocapzip.archive.settings.Settings.chain`), so a reader needs nothing else to decode.

| kind | what it does | where the stages live |
|---|---|---|
| representation | a clip's AMC channels <-> the pose matrix the codec compresses | `mocapzip/representations/` |
| transform | a curve along time <-> as many coefficients | `mocapzip/codec/temporal.py` |
| quantiser | coefficients <-> integers | `mocapzip/codec/quantise.py` |
| coefficient coder | integer matrices <-> bytes of a lossy stream | `mocapzip/codec/entropy/coefficients.py` (`mocapzip/legacy/streams.py`: format 1's) |
| lossless coder | AMC channel values <-> bytes, exactly | `mocapzip/codec/lossless.py` |

A new stage is one class in its kind's place, registered; `mcz --help`'s choices, the archive
schema and the contract tests (tests/test_stage_contracts.py) pick it up from here.
"""

from __future__ import annotations

import importlib
import inspect
from typing import ClassVar

KINDS = ("representation", "transform", "quantiser", "coefficient coder", "lossless coder")

# The modules that define stages, imported when the registry is first asked (not at import
# time: they import this module for `Stage`, and the CLI starts without NumPy).
_STAGE_MODULES = ("mocapzip.representations", "mocapzip.codec.temporal", "mocapzip.codec.quantise",
                  "mocapzip.codec.entropy.coefficients", "mocapzip.codec.lossless", "mocapzip.legacy.streams")

_REGISTRY: dict[str, dict[str, type]] = {kind: {} for kind in KINDS}


class Stage:
    """A stage whose parameters are its config: equal configs, equal stages.

    Subclasses set `kind` and `codec_id`, and override `params()` when they have parameters
    (the keyword arguments of their constructor, JSON-safe).
    """

    kind: ClassVar[str]
    codec_id: ClassVar[str]
    param_schema: ClassVar[dict] = {}  # JSON Schema of each entry of `params()`, where an archive stores them

    def params(self) -> dict:
        return {}

    def get_config(self) -> dict:
        return {"id": self.codec_id, **self.params()}

    @classmethod
    def from_config(cls, config: dict):
        """Rebuild from `get_config()` output (the "id" entry is optional; other keys must be parameters)."""
        if config.get("id", cls.codec_id) != cls.codec_id:
            raise ValueError(f"{cls.kind} {cls.codec_id!r}: config of another stage {config!r}")
        params = {key: value for key, value in config.items() if key != "id"}
        try:
            return cls(**params)
        except TypeError as exc:  # an unknown or missing parameter
            raise ValueError(f"{cls.kind} {cls.codec_id!r}: bad config {config!r} ({exc})") from None

    def __repr__(self) -> str:
        args = ", ".join(f"{key}={value!r}" for key, value in self.params().items())
        return f"{type(self).__name__}({args})"

    def __eq__(self, other) -> bool:
        return type(other) is type(self) and other.get_config() == self.get_config()

    def __hash__(self) -> int:  # consistent with ==: equal configs (0.0 and -0.0 too) hash alike
        return hash((type(self), _frozen(self.get_config())))


def _frozen(value):
    """A config as nested tuples, hashable, equal where the config compares equal."""
    if isinstance(value, dict):
        return tuple(sorted((key, _frozen(item)) for key, item in value.items()))
    if isinstance(value, list):
        return tuple(_frozen(item) for item in value)
    return value


def register(cls: type) -> type:
    """Make `get_stage` know a stage class by its kind and `codec_id` (a class decorator)."""
    if cls.kind not in _REGISTRY:
        raise ValueError(f"{cls.__name__}: unknown stage kind {cls.kind!r} (kinds: {', '.join(KINDS)})")
    if inspect.isabstract(cls):  # e.g. a representation without its own decode (`Representation`)
        raise TypeError(f"{cls.kind} {cls.codec_id!r}: {cls.__name__} does not define "
                        f"{', '.join(sorted(cls.__abstractmethods__))}")
    existing = _REGISTRY[cls.kind].get(cls.codec_id)
    if existing is not None and existing is not cls:
        raise ValueError(f"{cls.kind} id {cls.codec_id!r} is already registered to {existing.__name__}")
    _REGISTRY[cls.kind][cls.codec_id] = cls
    return cls


def _loaded() -> dict[str, dict[str, type]]:
    for module in _STAGE_MODULES:
        importlib.import_module(module)
    return _REGISTRY


def stage_classes(kind: str) -> dict[str, type]:
    """{codec_id: class} of every registered stage of `kind`, in registration order."""
    return dict(_loaded()[kind])


def stage_ids(kind: str, written_only: bool = False) -> tuple[str, ...]:
    """The ids of `kind`; `written_only` leaves out the decode-only stages of old formats."""
    return tuple(codec_id for codec_id, cls in stage_classes(kind).items()
                 if not (written_only and getattr(cls, "decode_only", False)))


def get_stage(kind: str, config: dict):
    """Build a stage of `kind` from its config, e.g. ("transform", {"id": "dwt", "wavelet": "db4", "level": None})."""
    if not isinstance(config, dict) or "id" not in config:
        raise ValueError(f"{kind} config has no 'id': {config!r}")
    classes = stage_classes(kind)
    try:
        cls = classes[config["id"]]
    except (KeyError, TypeError):
        raise ValueError(f"unknown {kind} id {config['id']!r} (known: {', '.join(classes)})") from None
    return cls.from_config(config)
