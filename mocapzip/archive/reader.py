"""`mcz decompress` / `info` / `test`: an .mcz archive -> its clips, decoded on demand.

The reader trusts nothing in the file (`meta.validate`, `mocapzip.limits`) and reads the newest
format; what an older one does differently (`mocapzip.legacy.format_of`, which the container
asks) it takes from the archive's `format`, and its old layouts are decoded by
`mocapzip.legacy.streams`. Every clip goes through one decode tail
(`representations.weighted.DecodeTail`), as the encoder's error check does.
"""

from __future__ import annotations

import fnmatch
import functools
import os
import threading
from collections import defaultdict
from collections.abc import Callable, Iterator
from contextlib import closing
from pathlib import Path, PurePosixPath

import numpy as np

from mocapzip.archive.dictionaries import STREAM_DICTIONARIES, dictionary
from mocapzip.archive.meta import contents_of
from mocapzip.archive.meta import validate as validate_meta
from mocapzip.archive.settings import Settings
from mocapzip.archive.skeletons import decode_skeletons
from mocapzip.codec.segments import coded_range, join_decoded
from mocapzip.codec.basis import ClassBasis
from mocapzip.codec.clip_stream import CodedClip, reconstruct
from mocapzip.codec.tensor import TensorModel, prediction
from mocapzip.codec.entropy.coefficients import Priors, check_matrix_shape
from mocapzip.codec.entropy.zstd import decode_bytes
from mocapzip.codec.foot_lock import Stances, hold
from mocapzip.codec.lossless import decode_channels
from mocapzip.codec.patches import FramePatches, channel_steps
from mocapzip.formats.amc import AmcStyle, Motion
from mocapzip.formats.errors import MocapFormatError
from mocapzip.formats.mcz import ArchiveError, ArchiveReader, parse_json
from mocapzip.formats.text import (MAX_ABS_VALUE, check_folders, check_inside, check_not_folders, in_value_range,
                                   write_file_atomically)
from mocapzip.inputs.registry import InputFormat, input_formats, stored_format
from mocapzip.legacy import Format
from mocapzip.legacy import streams as old_streams
from mocapzip.limits import MAX_ABS_POSE, MAX_DECODED_STREAM_BYTES
from mocapzip.motion.contacts import foot_joints
from mocapzip.motion.skeleton import ChannelLayout, SkeletonModel
from mocapzip.motion.timewarp import path_of_moves
from mocapzip.parallel import imap, one_blas_thread, thread_imap, worker_state
from mocapzip.progress import progress
from mocapzip.representations.positions import DegeneratePose, flips_from_ranges
from mocapzip.representations.weighted import DecodeTail, skeleton_params


def _built_once(build: Callable) -> Callable:
    """An `Archive` method whose value for its arguments is built on first use and kept, its
    ArchiveError too (raised again at each use): once per archive, whichever decode thread asks
    first (`Archive.made_files`), so a skeleton's warnings are given once, as with one thread."""

    @functools.wraps(build)
    def once(self, *key):
        key = (build.__name__, *key)
        if key not in self._built:
            with self._building:
                if key not in self._built:
                    try:
                        self._built[key] = (build(self, *key[1:]), None)
                    except ArchiveError as exc:
                        self._built[key] = (None, exc)
        value, failure = self._built[key]
        if failure is not None:
            raise failure
        return value

    return once


class Archive:
    """An opened .mcz: metadata up front, clips decoded on demand (random access)."""

    def __init__(self, path, lazy_skeletons: bool = False):
        """`lazy_skeletons`: decode the skeletons stream when a skeleton is first asked for, not
        here (the Python API's open: on the shared CMU set it took 1.3 s, of 1.4 s), so a damaged
        one is an ArchiveError then; the commands read it here, before any file is written."""
        self.path = os.fspath(path)
        self._reader = ArchiveReader(path)
        self._built: dict[tuple, tuple] = {}  # (method, its arguments) -> (value, ArchiveError): `_built_once`
        self._building = threading.RLock()
        try:
            self.meta = self._json("meta")
            # every file a full decompress writes, each path checked to stay inside the output folder
            self.files = validate_meta(self.meta, self._reader.names(), self.path, self.format_version)
            if not lazy_skeletons:
                self._skeleton_texts()
            stored = {**self.format.settings_defaults, **self.meta["settings"]}  # with what older formats meant
            self.settings = Settings(**stored)
            coders = self.format.coders
            if not self.settings.lossless and self.settings.coefficient_coder not in coders:
                raise ArchiveError(f"meta: settings.coefficient_coder: {self.settings.coefficient_coder!r} is not "
                                   f"one format {self.format_version} writes ({', '.join(coders)})", self.path)
            transform = self.settings.transform.get("id") if isinstance(self.settings.transform, dict) else None
            if not self.settings.lossless and transform in self.format.later_transforms:
                raise ArchiveError(f"meta: settings.transform: {transform!r} is not one format {self.format_version} "
                                   "writes", self.path)
            if "axes_from_positions" not in stored:
                raise ArchiveError(f"meta: settings.axes_from_positions: missing (format {self.format_version} "
                                   "stores it)", self.path)
            try:
                self.stages = self.settings.stages()  # the chain the settings name, from the registry
            except ValueError as exc:
                raise ArchiveError(f"meta: settings: {exc}", self.path) from None
        except BaseException:
            self._reader.close()
            raise
        self._decode_class = old_streams.CLASS_DECODERS.get(self.format.class_stream, ClassBasis.decode)
        self._decode_clip = old_streams.CLIP_DECODERS.get(self.format.clip_stream, self._coded_clip)

    def _json(self, name):
        try:
            return parse_json(self._unpacked(name))
        except (ValueError, RecursionError) as exc:  # also bad UTF-8, bad JSON and JSON nested too deep
            raise ArchiveError(f"{name}: {exc}", self.path) from exc

    def _stream(self, name: str) -> bytes:
        try:
            return self._reader.read(name)
        except KeyError:
            raise ArchiveError(f"{name}: stream missing", self.path) from None

    def stream(self, name: str) -> bytes:
        """Stream `name` as stored, its CRC32 checked: what `mcz remove` and `mcz append` copy (`archive.edit`)."""
        return self._stream(name)

    def _unpacked(self, name: str) -> bytes:
        """Stream `meta` (or an old format's `skeletons`) unzstd'd, with its dictionary where the format has one."""
        used = dictionary(STREAM_DICTIONARIES[name]) if self.format.stream_dictionaries else None
        data = self._stream(name)
        try:
            return decode_bytes(data, dictionary=used)
        except ValueError as exc:
            raise ArchiveError(f"{name}: {exc}", self.path) from exc

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self._reader.close()

    @property
    def clips(self) -> list[dict]:
        return self.meta["clips"]

    @_built_once
    def _skeleton_texts(self) -> list[str]:
        """The ASF texts, one per skeleton in meta, each as it was read (Latin-1: one character per byte)."""
        count = len(self.meta["skeletons"])
        if self.format.skeletons != 10:  # an old format's layout (formats 1 to 9)
            try:
                return old_streams.skeleton_texts(self._unpacked("skeletons"), self.format.skeletons, count)
            except (ValueError, RecursionError) as exc:  # also bad JSON, and JSON nested too deep
                raise ArchiveError(f"skeletons: {exc}", self.path) from exc
        is_asf = [stored_format(entry).asf_skeletons for entry in self.meta["skeletons"]]
        try:  # templates and numbers (archive/skeletons.py)
            texts = [blob.decode("latin-1") for blob in
                     decode_skeletons(self._stream("skeletons"), is_asf, MAX_DECODED_STREAM_BYTES)]
        except ValueError as exc:
            raise ArchiveError(f"skeletons: {exc}", self.path) from exc
        if len(texts) != count:
            raise ArchiveError(f"skeletons: expected {count} ASF texts, as meta lists", self.path)
        return texts

    def skeleton_text(self, index: int) -> str:
        return self._skeleton_texts()[index]

    @property
    def priors(self) -> Priors | None:
        """Where the clip streams' models start (coefficient coder "primed"), else None."""
        if self.settings.lossless or not self.stages["coefficient coder"].needs_priors:
            return None
        return self._priors_table()

    @_built_once
    def _priors_table(self) -> Priors:
        try:
            return Priors.decode(decode_bytes(self._reader.read("priors")))
        except KeyError:
            raise ArchiveError("priors: stream missing", self.path) from None
        except ValueError as exc:
            raise ArchiveError(f"priors: damaged ({exc})", self.path) from exc

    def decode(self, index: int) -> Motion:
        """The clip's motion as decoded (lossy: within the stored error of the original)."""
        row = self.clips[index]
        name = f"clip/{index:05d}"
        try:
            if self.settings.lossless:
                values = self.stages["lossless coder"].decode(self._reader.read(name))
            else:
                model = self._model(row["skeleton"])
                layout = model.layout(ChannelLayout(tuple(row["bones"]), tuple(row["counts"]), row["angle_unit"]))
                if "segments" in row:  # --segment: the segments joined, then turned into channels in one go
                    decoded, cores = [], []
                    for part in row["segments"]:
                        name = part["stream"]
                        lo, hi = coded_range(part["first"], part["frames"], row["frames"], row["segment_overlap"])
                        decoded.append(self._reconstruct(name, part["class"], hi - lo))
                        cores.append((part["first"], part["frames"]))
                    poses, root = join_decoded(decoded, cores, row["frames"], row["segment_overlap"])
                else:
                    poses, root = self._reconstruct(name, row["class"], row["frames"])
                    if "tensor_at" in row:  # --model tensor: the stream coded what the class's model misses
                        name = f"warp/{index:05d}"
                        poses = poses + self._prediction(row, self._reader.read(name), poses.shape[1])
                if not np.all(np.abs(poses) <= MAX_ABS_POSE):  # an overflowing model or basis, or NaN
                    raise ValueError(f"decoded poses beyond +-{MAX_ABS_POSE:g}, or not numbers")
                twist = flips_from_ranges(row.get("twist_flips", {}), model, row["frames"])
                tail = self._decode_tail(row["skeleton"], layout)
                try:
                    tail.decoder.check_directions(poses)
                except DegeneratePose as exc:
                    raise ArchiveError(f"clip/{index:05d} ({row['path']}): damaged (class {row['class']}'s model and basis "
                                       f"decode to a degenerate pose: {exc})", self.path) from None
                values = tail.decode(poses, root, twist)
                if "planted_stances" in row:
                    name = f"plant/{index:05d}"
                    stances = Stances.from_payload(self._reader.read(name), row["planted_stances"], row["frames"],
                                                   len(foot_joints(model)))
                    hold(values, stances, model, tail)
                if "patched_frames" in row:
                    name = f"patch/{index:05d}"
                    patches = FramePatches.from_payload(self._reader.read(name), row["frames"], layout.width,
                                                        row["patched_frames"])
                    patches.apply(values, channel_steps(model, layout))
        except ArchiveError:
            raise
        except (ValueError, KeyError, IndexError, EOFError, MocapFormatError) as exc:
            raise ArchiveError(f"{name} ({row['path']}): damaged ({exc})", self.path) from exc
        if values.shape != (row["frames"], sum(row["counts"])):
            raise ArchiveError(f"{name} ({row['path']}): decoded shape {values.shape} does not match", self.path)
        frames = np.arange(row["first_frame"], row["first_frame"] + row["frames"])
        return Motion(row["bones"], row["counts"], values, frames, row["header"], row["path"], AmcStyle(**row["style"]))

    def file_bytes(self, kind: str, index: int) -> bytes:
        """The bytes `decompress` writes for an entry of `files`: ("motion", clip), as the clip's
        format writes it (`registry.InputFormat.write`), or ("skeleton", skeleton)."""
        return b"".join(self.file_blocks(kind, index))

    def file_blocks(self, kind: str, index: int) -> Iterator[bytes]:
        """`file_bytes` in blocks of whole frames, made as they are asked for: a clip at the size
        limits (100 MB of text) is never one string.

        A clip that mcz could not read back (values it refuses) is an error here, not a file.
        """
        if kind == "skeleton":
            yield self.skeleton_text(index).encode("latin-1")
            return
        yield from self.clip_format(index).write(self, index)

    def clip_format(self, index: int) -> InputFormat:
        """The input format of clip `index`: its skeleton's (`registry.stored_format`, checked by `meta.validate`)."""
        return stored_format(self.meta["skeletons"][self.clips[index]["skeleton"]])

    def damaged(self, index: int, problem: str) -> ArchiveError:
        """The error for clip `index`, whose streams decode to something its row and skeleton cannot be."""
        return ArchiveError(f"clip/{index:05d} ({self.clips[index]['path']}): damaged ({problem})", self.path)

    def check_range(self, index: int, values: np.ndarray) -> None:
        """ArchiveError for a value no reader would take back: NaN, or beyond +-MAX_ABS_VALUE."""
        if not in_value_range(values):
            raise self.damaged(index, f"decoded values beyond +-{MAX_ABS_VALUE:g}, which no reader accepts")

    def extra_root(self, index: int, width: int) -> np.ndarray:
        """A lossy clip's `width` channels kept exactly beside its coded ones (stream extra_root/NNNNN: a
        BVH clip's extra root), checked to be one row per frame."""
        row, name = self.clips[index], f"extra_root/{index:05d}"
        try:
            values = decode_channels(self._reader.read(name))
        except (ValueError, KeyError, IndexError, EOFError) as exc:
            raise ArchiveError(f"{name} ({row['path']}): damaged ({exc})", self.path) from exc
        if values.shape != (row["frames"], width):
            raise ArchiveError(f"{name} ({row['path']}): damaged ({values.shape[1]} channels of {values.shape[0]} "
                               f"frames, the clip needs {width} of {row['frames']})", self.path)
        return values

    def _reconstruct(self, stream: str, class_index: int, n_frames: int):
        """Weighted poses and root track of one coefficient stream (a clip, or a segment's coded frames)."""
        basis = self.basis(class_index)
        check_matrix_shape(n_frames, basis.mean.size)  # the decoded poses: bounded before they are made
        root_width = self.stages["representation"].root_width
        with_root = root_width > 0
        shapes = [(n_frames, basis.q), (n_frames, root_width)][: 2 if with_root else 1]
        coded = self._decode_clip(self._reader.read(stream), shapes)
        if (coded.root_ints is not None) != with_root:
            raise ValueError(f"{'no' if with_root else 'a'} root track matrix, where the representation "
                             f"{'has' if with_root else 'has none'}")
        return reconstruct(coded, basis, self.stages["transform"], self.settings.dead_zone, n_frames)

    def _prediction(self, row: dict, moves: bytes, width: int) -> np.ndarray:
        """A tensor class's prediction of the clip of `row` (`codec.tensor.prediction`), on
        the path its stored `moves` give, checked against the class's model before it is made."""
        model = self._tensor_model(row["class"], width)
        frames = model.factors[0].shape[0]
        path = path_of_moves(decode_bytes(moves, frames + row["frames"]), frames, row["frames"])
        return prediction(model, tuple(row["tensor_at"]), path)

    @_built_once
    def _tensor_model(self, k: int, width: int) -> TensorModel:
        """Class k's model, its sizes checked against the class (`TensorModel.decode`): the frames of
        its longest clip (the timeline its clips are warped to), its basis's `width`, its grid's levels."""
        name, levels = f"tensor/{k:04d}", self.meta["classes"][k]["levels"]
        frames = max(row["frames"] for row in self.clips if row["class"] == k)  # its clips have tensor_at (meta)
        try:
            model = TensorModel.decode(self._reader.read(name), (frames, width, *map(len, levels)))
        except (ValueError, EOFError) as exc:
            raise ArchiveError(f"{name}: damaged ({exc})", self.path) from exc
        return model

    def _coded_clip(self, blob: bytes, shapes) -> CodedClip:
        return CodedClip.from_payload(blob, self.settings.coefficient_coder, shapes, self.priors)

    def _model(self, k: int) -> SkeletonModel:
        return self.stored_skeleton(k)[1]

    @_built_once
    def stored_skeleton(self, k: int) -> tuple:
        """(skeleton, model) of skeleton k, as its format reads it (`registry.InputFormat.stored`);
        a lossless archive's BVH hierarchy has no model, which its clips do not need."""
        entry = self.meta["skeletons"][k]
        try:
            return stored_format(entry).stored(self.skeleton_text(k).encode("latin-1"), entry, self.settings.lossless)
        except ValueError as exc:
            raise ArchiveError(f"skeletons: skeleton {k} {exc}", self.path) from exc

    @_built_once
    def _decode_tail(self, k: int, layout: ChannelLayout) -> DecodeTail:
        """The decode tail of skeleton k's clips with this layout: its tables and the
        representation's skeleton params (a rest pose through the encoder) cost more than
        decoding a short clip."""
        model, representation = self._model(k), self.stages["representation"]
        return DecodeTail(model, representation, layout, skeleton_params(model, representation, layout),
                          self.settings.axis_weight_cm)

    @_built_once
    def basis(self, k: int) -> ClassBasis:
        """Class k's basis as decoders use it (quantised), checked against meta; decoded once."""
        name = f"class/{k:04d}"
        try:
            basis = self._decode_class(self._reader.read(name))
        except (ValueError, KeyError) as exc:
            raise ArchiveError(f"{name}: damaged ({exc})", self.path) from exc
        stated = self.meta["classes"][k]["components"]
        if basis.q != stated:  # meta's count is the one `info` shows: it must be the basis's
            raise ArchiveError(f"meta: classes[{k}].components: {stated}, but {name} holds a basis of {basis.q}",
                               self.path)
        return basis

    def stream_sizes(self) -> dict[str, int]:
        return self._reader.sizes()

    @property
    def format_version(self) -> int:
        return self._reader.format_version

    @property
    def format(self) -> Format:
        """What the archive's format does differently from the newest (`mocapzip.legacy.format_of`)."""
        return self._reader.format

    def verify_checksums(self) -> None:
        """Check every stream's CRC32 without decoding: cheap, so `info` and `decompress` run it first."""
        paths = {f"{kind}/{i:05d}": row["path"] for i, row in enumerate(self.clips)
                 for kind in ("clip", "patch", "plant", "extra_root")}
        for name in self._reader.names():
            try:
                self._reader.read(name)
            except ArchiveError as exc:
                clip = paths.get("/".join(name.split("/")[:2]))  # clip/NNNNN, its segments clip/NNNNN/SSS, patch/NNNNN
                if clip is None:
                    raise
                raise ArchiveError(f"{exc.message} (clip {clip})", self.path) from exc

    def verify(self, jobs: int = 1) -> None:
        """Check every stream's checksum and make every file a full `decompress` writes, in memory
        (`mcz test`): an archive that passes decompresses, disk space and permissions aside. Also
        checks that the index's clips table (format 10 on, where written) says what meta says."""
        self.verify_checksums()
        if self._reader.contents not in (None, contents_of(self.meta, self.format.contents_columns)):
            raise ArchiveError("index: contents (the clips table) does not match meta", self.path)
        entries = list(self.files.values())
        with closing(self.made_files(entries, jobs, keep=False)) as made:
            for _ in progress(made, total=len(entries), desc="test", unit="file"):
                pass

    def made_files(self, entries: list[tuple[str, int]], jobs: int = 1, keep: bool = True):
        """`file_blocks` of each (kind, index) of `entries` as a list, in order, made by `jobs` threads,
        or worker processes for a lossless archive (None each if not `keep`: only checked, each block
        dropped once made). A few files ahead of the one yielded are made at once (FILES_AHEAD per
        job), never all of them; the first that fails raises at its turn. Close the generator if you
        may stop early."""
        if self.settings.lossless:
            yield from self._made_in_processes(entries, jobs, keep)
            return
        # Lossy clips decode in numba kernels that release the GIL: threads, which need no file
        # pickled back from a worker (the shared CMU set at 1 cm, -j 2: 0.89x the time of worker
        # processes). What the threads share is built once (`_built_once`); the skeletons first,
        # here, in the order of their first clips, so that their warnings come in -j 1's order.
        for k in dict.fromkeys(self.clips[index]["skeleton"] for kind, index in entries if kind == "motion"):
            try:
                self._model(k)
            except ArchiveError:
                pass  # raised again at its first clip's turn, after the files before it

        def made(entry: tuple[str, int]) -> list[bytes] | None:
            return _kept(self.file_blocks(*entry), keep)

        yield from thread_imap(made, entries, jobs, FILES_AHEAD * jobs)

    def _made_in_processes(self, entries: list[tuple[str, int]], jobs: int, keep: bool):
        """`made_files` in forked workers (`parallel.imap`): lossless clips decode their rANS
        streams in Python, which holds the GIL (threads took 1.6x the time of processes on the
        shared CMU set). The workers read this archive's open file: opening it again in each
        measured no faster (HDF5 reads with pread; every stream read is checked against its CRC32)."""
        _SHARED["archive"] = self
        clips = [entry for entry in entries if entry[0] == "motion"]
        if jobs > 1 and len(clips) > 1:  # decode one clip here first: numba loads its kernels once, before the
            _kept(self.file_blocks(*clips[0]), False)  # fork, not once in each worker (about a second each)
        try:
            yield from imap(_made_file if keep else _checked_file, entries, jobs, FILES_AHEAD * jobs)
        finally:
            _SHARED.clear()


@one_blas_thread
def decompress(archive_path, out_dir, patterns=(), force: bool = False, jobs: int = 1) -> dict:
    """Write the files of the clips matching `patterns` (all by default), and of their skeletons,
    under `out_dir`, made by `jobs` threads (worker processes for a lossless archive:
    `Archive.made_files`) and written here one at a time, in the archive's order.

    Every path comes from the archive's meta, checked on opening to be relative, free of '.'
    and '..' and unique (`meta.validate`); each file is also refused if its folder resolves
    outside `out_dir` through a symbolic link already there.
    """
    out = Path(out_dir)
    with Archive(archive_path) as archive:
        archive.verify_checksums()  # a damaged archive is refused before any file is written
        chosen = {i for i, row in enumerate(archive.clips)
                  if not patterns or any(path_matches(row["path"], p) for p in patterns)}
        if not chosen:
            raise MocapFormatError(f"no clip matches {', '.join(patterns)}", archive_path)
        folders = {PurePosixPath(archive.clips[i]["path"]).parent for i in chosen}
        targets = {out.joinpath(*path.split("/")): (kind, index) for path, (kind, index) in archive.files.items()
                   if (index in chosen if kind == "motion" else PurePosixPath(path).parent in folders)}
        check_inside(out, targets)
        check_folders(path.parent for path in targets)
        check_not_folders(targets)
        existing = [p for p in targets if os.path.lexists(p)]
        if existing and not force:
            raise FileExistsError(None, "already exists", os.fspath(existing[0]))
        frames = 0
        entries = list(targets.items())
        with progress(total=len(entries), desc="decompress", unit="file") as bar, \
                closing(archive.made_files([entry for _, entry in entries], jobs)) as made:
            for (path, (kind, index)), blocks in zip(entries, made):
                write_file_atomically(path, *blocks)
                frames += archive.clips[index]["frames"] if kind == "motion" else 0
                bar.update()
    return {"clips": len(chosen), "frames": frames, "files": len(targets), "output": os.fspath(out)}


def path_matches(path: str, pattern: str) -> bool:
    """Whether a clip's stored `path` ("09/09_01.amc") or its file's name ("09_01.amc") matches the
    shell-style `pattern` (case-sensitive on every system): "09_*" finds what "09/*" does."""
    return fnmatch.fnmatchcase(path, pattern) or fnmatch.fnmatchcase(PurePosixPath(path).name, pattern)


FILES_AHEAD = 2  # files made ahead of the one being written, per job: enough to keep every thread or worker busy

_SHARED = worker_state(__name__)  # the archive the forked workers decode from (`Archive._made_in_processes`)


def _kept(blocks: Iterator[bytes], keep: bool) -> list[bytes] | None:
    """A file's blocks (`Archive.file_blocks`), all of them, or (not `keep`) each dropped once made."""
    if keep:
        return list(blocks)
    for _ in blocks:
        pass
    return None


def _made_file(entry: tuple[str, int]) -> list[bytes]:
    return _kept(_SHARED["archive"].file_blocks(*entry), True)


def _checked_file(entry: tuple[str, int]) -> None:
    _kept(_SHARED["archive"].file_blocks(*entry), False)


def info(archive_path) -> dict:
    """What `mcz info` shows: settings, classes, per-clip frames and achieved errors, sizes."""
    size = os.path.getsize(archive_path)
    with Archive(archive_path) as archive:
        archive.verify_checksums()  # info on a damaged archive says so (decoding is left to `mcz test`)
        meta, format_version = archive.meta, archive.format_version
        stream_sizes = defaultdict(int)
        for name, length in archive.stream_sizes().items():
            stream_sizes[name.split("/")[0]] += length
    frames = sum(r["frames"] for r in meta["clips"])
    largest_mean = max((r["error_cm"] for r in meta["clips"]), default=0.0)
    return {
        "path": os.fspath(archive_path),
        "format_version": format_version,
        "tool": meta["tool"],
        "settings": meta["settings"],
        "skeletons": len(meta["skeletons"]),
        # each format's but ASF's (format 8 on; `InputFormat.info`): BVH's, the unit of their lengths and
        # whether compress inferred it
        **{f"{f.name}_skeletons": f.info([s for s in meta["skeletons"] if stored_format(s) is f])
           for f in input_formats() if not f.asf_skeletons},
        "classes": meta["classes"],
        "auto_classes": meta.get("auto_classes", []),
        "clips": [_info_row(r, meta["settings"]["fps"]) for r in meta["clips"]],
        "frames": frames,
        "bytes": size,
        "bytes_per_frame": size / frames if frames else 0.0,
        "stream_bytes": dict(stream_sizes),
        "worst_error_cm": largest_mean,  # = largest_mean_error_cm, kept for old readers
        "largest_mean_error_cm": largest_mean,  # what -e bounds
        "largest_max_error_cm": max((r["max_error_cm"] for r in meta["clips"]), default=0.0),
        # format 13 on, lossy: the worst shell vertex (ACL's metric) of any clip; None where not stored
        "largest_max_vertex_error_cm": max((r["max_vertex_error_cm"] for r in meta["clips"] if "max_vertex_error_cm" in r),
                                           default=None),
        "skipped": meta.get("skipped", []),  # clips left out by compress --skip-bad
        "dropped_frames": sum(r.get("dropped_frames", 0) for r in meta["clips"]),  # of truncated inputs
    }


def _info_row(row: dict, fps: float) -> dict:
    """A clip as `info` lists it, with its frame rate (its row's, format 7 on, else the settings'
    `fps`); a segmented take (--segment) with its segments' frames, classes and errors."""
    out = {k: row[k] for k in ("path", "frames", "class", "error_cm", "max_error_cm")}
    out["fps"] = row.get("fps", fps)
    # p99: format 5 on; patches: a bound; repaired: --repair-glitches (format 6 on); vertex: format 13 on, lossy
    for optional in ("p99_error_cm", "max_vertex_error_cm", "patched_frames", "dropped_frames", "repaired"):
        if optional in row:
            out[optional] = row[optional]
    if "segments" in row:
        out["segments"] = [{k: s[k] for k in ("first", "frames", "class", "error_cm", "max_error_cm")}
                           for s in row["segments"]]
    return out
