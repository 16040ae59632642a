"""`mcz compress` / `decompress` / `info`: clips on disk <-> the streams of one .mcz archive.

Streams (see docs/format.md, "Streams written by the codec"):
  meta        zstd JSON: settings, skeleton and class tables, one row per clip
  skeletons   zstd JSON list of the ASF texts, byte for byte (they compress well together)
  class/NNNN  a class's quantised PCA mean and basis (lossy mode)
  clip/NNNNN  a clip's coefficient payload (lossy) or lossless channel code
"""

from __future__ import annotations

import fnmatch
import json
import os
import time
from collections import defaultdict
from dataclasses import asdict, dataclass, field
from pathlib import Path, PurePosixPath

import numpy as np

from . import __version__
from .classes import assign_classes
from .clip import LoadedClip, channels_from, load_clips, pose_weights, skeleton_params
from .codec import get_stage
from .codec.entropy import decode_bytes, encode_bytes
from .codec.lossless import decode_channels, encode_channels
from .formats.amc import AmcStyle, Motion, format_amc
from .formats.asf import parse_asf
from .formats.errors import MocapFormatError
from .formats.mcz import ArchiveError, ArchiveReader, write_archive
from .inputs import find_clips
from .lossy import ClassBasis, CodedClip, encode_class, reconstruct
from .skeleton import ChannelLayout, SkeletonModel
from .progress import progress

DEFAULT_ERROR_CM = 1.0


@dataclass
class Settings:
    """Everything that decides the archive's content; stored in it as JSON."""

    error_cm: float = DEFAULT_ERROR_CM
    representation: str = "aligned"
    transform: dict = field(default_factory=lambda: {"id": "dct"})
    classes: str = "subject"
    split: list[float] | None = None  # forced R, P, T shares of error_cm
    dead_zone: float = 0.2
    basis_precision: float = 0.02  # basis rounding error per direction, as a share of error_cm
    axis_weight_cm: float = 10.0  # weight of bone axis vectors against joint positions (clip.pose_weights)
    fps: float = 120.0
    lossless: bool = False


def compress(inputs, output, settings: Settings, asf=None, force: bool = False, jobs: int = 1) -> dict:
    """Compress every clip under `inputs` into `output`; return the summary (also stored in meta)."""
    if not force and os.path.lexists(output):
        raise FileExistsError(None, "already exists", os.fspath(output))
    started = time.perf_counter()
    sources = find_clips(inputs, asf=asf)
    if not sources:
        raise MocapFormatError("no AMC clips found", ", ".join(map(os.fspath, inputs)))
    skeleton_paths = sorted({s.asf for s in sources})
    skeleton_texts = [p.read_bytes().decode("latin-1") for p in skeleton_paths]
    representation = None if settings.lossless else settings.representation
    clips = load_clips(sources, skeleton_paths, representation, settings.axis_weight_cm)
    class_of = assign_classes(sources, settings.classes)
    class_names = sorted(set(class_of.values()))

    streams: dict[str, bytes] = {}
    rows = [_clip_row(c, class_names.index(class_of[c.source.relpath])) for c in clips]
    classes_meta = []
    if settings.lossless:
        for i, clip in enumerate(progress(clips, desc="lossless", unit="clip")):
            streams[f"clip/{i:05d}"] = encode_channels(clip.motion.values)
            rows[i].update(error_cm=0.0, max_error_cm=0.0)
    else:
        transform = get_stage(settings.transform)
        for k, name in enumerate(progress(class_names, desc="classes", unit="class")):
            members = [i for i, c in enumerate(clips) if class_of[c.source.relpath] == name]
            basis, coded, errors = encode_class([clips[i] for i in members], transform, settings, jobs)
            streams[f"class/{k:04d}"] = basis.encode()
            classes_meta.append({"name": name, "components": basis.q, "clips": len(members),
                                 "frames": sum(clips[i].motion.n_frames for i in members)})
            for i, code, (mean_err, max_err) in zip(members, coded, errors):
                streams[f"clip/{i:05d}"] = code.payload()
                rows[i].update(error_cm=mean_err, max_error_cm=max_err)

    meta = {
        "tool": f"mocapzip {__version__}",
        "settings": asdict(settings),
        "skeletons": [{"name": p.name} for p in skeleton_paths],
        "classes": classes_meta if not settings.lossless else [],
        "clips": rows,
    }
    ordered = {"meta": encode_bytes(json.dumps(meta, sort_keys=True).encode()),
               "skeletons": encode_bytes(json.dumps(skeleton_texts).encode())}
    ordered.update(sorted(streams.items()))
    size = write_archive(output, ordered, tool_version=__version__, overwrite=force)
    frames = sum(r["frames"] for r in rows)
    return {
        "output": os.fspath(output),
        "clips": len(rows),
        "frames": frames,
        "input_bytes": sum(os.path.getsize(s.amc) for s in sources) + sum(os.path.getsize(p) for p in skeleton_paths),
        "output_bytes": size,
        "bytes_per_frame": size / frames,
        "worst_error_cm": max(r["error_cm"] for r in rows),
        "seconds": time.perf_counter() - started,
    }


def _clip_row(clip: LoadedClip, class_index: int) -> dict:
    m = clip.motion
    return {
        "path": clip.source.relpath,
        "skeleton": clip.skeleton_index,
        "class": class_index,
        "frames": m.n_frames,
        "first_frame": int(m.frame_numbers[0]) if m.n_frames else 1,
        "header": m.header,
        "bones": m.bones,
        "counts": m.counts,
        "angle_unit": clip.layout.angle_unit,
        "style": asdict(m.style),  # how the source wrote numbers and lines, to write it back alike
    }


class Archive:
    """An opened .mcz: metadata up front, clips decoded on demand (random access)."""

    def __init__(self, path):
        self.path = os.fspath(path)
        self._reader = ArchiveReader(path)
        try:
            self.meta = self._json("meta")
            self.settings = Settings(**self.meta["settings"])
        except (KeyError, TypeError, ValueError) as exc:
            self._reader.close()
            raise ArchiveError(f"meta: invalid ({exc})", self.path) from exc
        self._skeleton_texts = None
        self._bases: dict[int, ClassBasis] = {}
        self._models: dict[int, SkeletonModel] = {}
        self._transform = get_stage(self.settings.transform)

    def _json(self, name):
        try:
            return json.loads(decode_bytes(self._reader.read(name)))
        except KeyError:
            raise ArchiveError(f"{name}: stream missing", self.path) from None
        except ValueError as exc:
            raise ArchiveError(f"{name}: {exc}", self.path) from exc

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self._reader.close()

    @property
    def clips(self) -> list[dict]:
        return self.meta["clips"]

    def skeleton_text(self, index: int) -> str:
        if self._skeleton_texts is None:
            self._skeleton_texts = self._json("skeletons")
        return self._skeleton_texts[index]

    def decode(self, index: int) -> Motion:
        """The clip's motion as decoded (lossy: within the stored error of the original)."""
        row = self.clips[index]
        name = f"clip/{index:05d}"
        try:
            blob = self._reader.read(name)
            if self.settings.lossless:
                values = decode_channels(blob)
            else:
                model = self._model(row["skeleton"])
                layout = model.layout(ChannelLayout(tuple(row["bones"]), tuple(row["counts"]), row["angle_unit"]))
                name_ = self.settings.representation
                poses, root = reconstruct(CodedClip.from_payload(blob), self._basis(row["class"]), self._transform,
                                          self.settings.dead_zone, row["frames"])
                poses = poses / pose_weights(model, name_, poses.shape[1], self.settings.axis_weight_cm)
                values = channels_from(model, name_, layout, poses, root, skeleton_params(model, name_, layout))
        except (ValueError, KeyError, IndexError, EOFError) as exc:
            raise ArchiveError(f"{name} ({row['path']}): damaged ({exc})", self.path) from exc
        if values.shape != (row["frames"], sum(row["counts"])):
            raise ArchiveError(f"{name} ({row['path']}): decoded shape {values.shape} does not match", self.path)
        frames = np.arange(row["first_frame"], row["first_frame"] + row["frames"])
        return Motion(row["bones"], row["counts"], values, frames, row["header"], row["path"], AmcStyle(**row["style"]))

    def _model(self, k: int) -> SkeletonModel:
        if k not in self._models:
            self._models[k] = SkeletonModel.from_asf(parse_asf(self.skeleton_text(k).encode("latin-1"), f"skeleton {k}"))
        return self._models[k]

    def _basis(self, k: int) -> ClassBasis:
        if k not in self._bases:
            name = f"class/{k:04d}"
            try:
                self._bases[k] = ClassBasis.decode(self._reader.read(name))
            except (ValueError, KeyError) as exc:
                raise ArchiveError(f"{name}: damaged ({exc})", self.path) from exc
        return self._bases[k]

    def stream_sizes(self) -> dict[str, int]:
        return self._reader.sizes()

    @property
    def format_version(self) -> int:
        return self._reader.format_version

    def verify(self) -> None:
        """Check every stream's checksum and decode every clip (`mcz test`)."""
        self._reader.verify()
        for i in progress(range(len(self.clips)), desc="test", unit="clip"):
            self.decode(i)


def decompress(archive_path, out_dir, patterns=(), force: bool = False) -> dict:
    """Write the ASF and AMC files of the clips matching `patterns` (all by default) under `out_dir`."""
    out = Path(out_dir)
    with Archive(archive_path) as archive:
        chosen = [i for i, row in enumerate(archive.clips)
                  if not patterns or any(fnmatch.fnmatch(row["path"], p) for p in patterns)]
        if not chosen:
            raise MocapFormatError(f"no clip matches {', '.join(patterns)}", archive_path)
        targets = {}
        for i in chosen:
            row = archive.clips[i]
            targets[out / row["path"]] = ("amc", i)
            skeleton_name = archive.meta["skeletons"][row["skeleton"]]["name"]
            targets.setdefault(out / PurePosixPath(row["path"]).parent / skeleton_name, ("asf", row["skeleton"]))
        existing = [p for p in targets if p.exists()]
        if existing and not force:
            raise FileExistsError(None, "already exists", os.fspath(existing[0]))
        frames = 0
        for path, (kind, index) in progress(list(targets.items()), desc="decompress", unit="file"):
            if kind == "asf":
                _write_atomically(path, archive.skeleton_text(index).encode("latin-1"))
            else:
                motion = archive.decode(index)
                frames += motion.n_frames
                _write_atomically(path, format_amc(motion).encode(motion.style.encoding, errors="replace"))
    return {"clips": len(chosen), "frames": frames, "files": len(targets), "output": os.fspath(out)}


def _write_atomically(path: Path, data: bytes) -> None:
    """Temp file then rename: an interrupted run never leaves half an AMC behind."""
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.tmp-{os.getpid()}")
    try:
        tmp.write_bytes(data)
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise


def info(archive_path) -> dict:
    """What `mcz info` shows: settings, classes, per-clip frames and achieved errors, sizes."""
    size = os.path.getsize(archive_path)
    with Archive(archive_path) as archive:
        meta, format_version = archive.meta, archive.format_version
        stream_sizes = defaultdict(int)
        for name, length in archive.stream_sizes().items():
            stream_sizes[name.split("/")[0]] += length
    frames = sum(r["frames"] for r in meta["clips"])
    return {
        "path": os.fspath(archive_path),
        "format_version": format_version,
        "tool": meta["tool"],
        "settings": meta["settings"],
        "skeletons": len(meta["skeletons"]),
        "classes": meta["classes"],
        "clips": [{k: r[k] for k in ("path", "frames", "class", "error_cm", "max_error_cm")} for r in meta["clips"]],
        "frames": frames,
        "bytes": size,
        "bytes_per_frame": size / frames if frames else 0.0,
        "stream_bytes": dict(stream_sizes),
        "worst_error_cm": max((r["error_cm"] for r in meta["clips"]), default=0.0),
    }
