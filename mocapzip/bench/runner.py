"""`mcz bench`: compress, decompress and measure, against baselines, in one report.

What is measured, and how (the same text goes into every JSON report under "rules"):

* Clips are what `mcz compress` would store: every AMC under the inputs, paired with
  its skeleton, and every BVH file (`mocapzip.inputs.discover.find_clips`). A BVH clip's
  joints are its joints and End Sites (`mocapzip.motion.bvh_skeleton`).
* mcz runs are real archives. `mcz compress` and `mcz decompress` run in child
  processes (so their peak memory is the child's `ru_maxrss`, and their time excludes
  interpreter start-up), the decompressed AMC and ASF (or BVH) files are read back with
  `mocapzip.formats`, run through forward kinematics and compared with the originals. The codec's own error estimate is never used.
* Bytes of a clip in an archive: its `clip/NNNNN` stream, plus its class's `class/NNNN`
  stream shared among the clips of that class in proportion to frames, plus everything
  else in the file (meta, skeletons, container overhead) shared among all clips in
  proportion to frames. Clip bytes add up to the archive's size on disk exactly.
  "Payload" is the clip's own stream only.
* Ratios are reference bytes / compressed bytes, with three references: the AMC text
  on disk; float32 channels (AMC values per frame x 4 bytes); float32 joint positions
  (joints x 3 x 4 bytes per frame: 31 x 3 x 4 = 372 for CMU, Hou et al.'s definition).
* Joint error: Euclidean distance (cm) of each joint in each frame between forward
  kinematics of the original and of the decoded clip (Hou et al. eq. 11); mean over
  joints and frames, 99th percentile and maximum over every joint of every frame.
  Skin error: thesis eq. 3.1 on the faux mesh (`mocapzip.motion.metrics.skin_error`).
  Worst vertex (mcz): ACL's error metric, the worst distance of any virtual vertex a shell
  distance (`--shell-cm`, 3 cm as ACL) from any bone, in any frame, in object space
  (`mocapzip.motion.metrics.shell_errors`, docs/acl.md); it sees an end bone's twist, which
  moves no joint. Hou et al. store no rotations (none); lossless codecs 0.
* Speed: frames / seconds. Encode: from AMC files on disk to compressed bytes on disk;
  decode: from compressed bytes to AMC files on disk (mcz, xz, zstd). Hou et al.
  decode to joint positions in memory (the codec has no AMC output); its encode time
  includes parsing the AMC and forward kinematics but not its parameter search
  (reported separately as `search_seconds`).
* xz -9 / zstd -19: each AMC file compressed on its own (`lzma` preset 9, `zstandard`
  level 19), like `xz -9 *.amc`; the skeleton files too, their bytes shared among the
  clips using them in proportion to frames. Lossless, checked byte for byte.
* Hou et al. 2015 (`mocapzip.bench.baselines.hou`): codes joint positions only, so its
  error is measured on joint positions directly (no AMC text, no skin error). For each
  target error, each clip gets the parameters (L, k, Q) from a grid with the fewest
  bytes that meet the target (`hou`: section IV, each clip coded alone with its own
  basis). `hou-shared`: one basis per subject (skeleton), as mcz's `subject` classes
  share theirs (section V with K = 1 per subject): L and k chosen per subject for the
  fewest bytes with every clip within the target, Q per clip; a clip's bytes are its
  stream plus its share of the basis in proportion to frames.
* `--classes none` (no PCA) is not an archive mode: the bench codes each clip with the
  codec's own stages (representation, temporal transform, dead-zone quantiser, entropy
  coder, step search) and an identity basis that costs nothing; bytes are the clip
  payloads; errors still go through AMC text read back by `mocapzip.formats`.
"""

from __future__ import annotations

import itertools
import json
import lzma
import os
import platform
import struct
import subprocess
import sys
import tempfile
import time
import warnings
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from mocapzip import __version__
from mocapzip.classes.by_name import read_class_table
from mocapzip.cli.choices import contact_error_cm, max_error_cm
from mocapzip.defaults import ACL_SHELL_CM, AUTO_REPRESENTATION, BLAS_THREAD_VARIABLES, DEFAULT_FPS
from mocapzip.formats.errors import MocapFormatError
from mocapzip.inputs.discover import ClipSource, find_clips, no_clips
from mocapzip.progress import progress

CODECS = ("mcz", "hou", "hou-shared", "xz", "zstd")
XZ_PRESET = 9
ZSTD_LEVEL = 19
NO_PCA = "none"  # --classes none: the bench-only "PCA off" emulation
CLASS_PER_CLIP = "clip"  # --classes clip: one PCA class per clip, in a real archive

RULES = __doc__.split("What is measured, and how", 1)[1].split("\n", 2)[2].strip()


class BenchError(MocapFormatError):
    """A failure inside a benchmark step (a child process, a decode that does not match)."""


@dataclass
class BenchOptions:
    inputs: list
    errors: list = field(default_factory=lambda: [1.0])
    representations: list = field(default_factory=lambda: [AUTO_REPRESENTATION])
    transforms: list = field(default_factory=lambda: ["dct-edges"])
    classes: list = field(default_factory=lambda: ["pooled"])
    splits: list = field(default_factory=lambda: [None])
    codecs: list = field(default_factory=lambda: list(CODECS))
    asf: str | None = None
    groups: str | None = None  # table clip -> motion class for the per-class report
    jobs: int = 1
    wavelet: str = "db4"
    max_error: float | str | None = None  # --max-error: a bound in cm, "none", or None for compress's default (5 x -e)
    contact_error: float | str | None = None  # --contact-error: a bound in cm, "none", or None for compress's default
    plant_feet: bool = False  # --plant-feet: the decoder holds planted feet still (codec.foot_lock)
    hou_grid: dict | None = None  # override of hou.GRID_L/K/Q (tests, quick runs)
    units: str | None = None  # --units: of BVH lengths, where they cannot be inferred
    shell_cm: float = ACL_SHELL_CM  # --shell-cm: the shell distance of the worst-vertex error (ACL's metric)
    quiet: bool = False
    command: str | None = None  # how the run was invoked (default: the equivalent `mcz bench` command)


@dataclass
class Clip:
    source: ClipSource
    group: str
    frames: int
    amc_bytes: int
    channels: int  # AMC values per frame
    joints: int  # joint positions per frame (31 for CMU)
    fps: float = DEFAULT_FPS  # its files' rate, else 120 (`inputs.clip.clip_frame_rate`): skate is a speed

    @property
    def path(self) -> str:
        return self.source.relpath

    @property
    def f32_channel_bytes(self) -> int:
        return self.frames * self.channels * 4

    @property
    def f32_position_bytes(self) -> int:
        return self.frames * self.joints * 3 * 4


# ----------------------------------------------------------------------------- entry point


def run_bench(options: BenchOptions) -> dict:
    """Run every configuration of `options` on the same clips; return the report (JSON-ready)."""
    started = time.time()
    load_start = os.getloadavg() if hasattr(os, "getloadavg") else None
    unknown = sorted(set(options.codecs) - set(CODECS))
    if unknown:
        raise MocapFormatError(f"unknown codec {unknown[0]!r}; choose from {', '.join(CODECS)}")
    sources = find_clips(options.inputs, asf=options.asf)
    if not sources:
        raise no_clips(options.inputs)
    clips, reader = _load_clips(sources, options)
    runs = []
    with tempfile.TemporaryDirectory(prefix="mcz-bench-") as tmp:
        tasks = _tasks(options)
        for task in progress(tasks, desc="bench", unit="run"):
            kind = task["codec"]
            if kind == "mcz" and task["classes"] == NO_PCA:
                runs.append(_run_mcz_without_pca(task, clips, reader, options))
            elif kind == "mcz":
                runs.append(_run_mcz(task, clips, reader, options, Path(tmp)))
            elif kind in ("xz", "zstd"):
                runs.append(_run_lossless(kind, clips, options, Path(tmp)))
            elif kind == "hou":
                runs.extend(_run_hou(task["errors"], clips, reader, options))
            elif kind == "hou-shared":
                runs.extend(_run_hou_shared(task["errors"], clips, reader, options))
    report = {
        "tool": f"mocapzip {__version__}",
        "command": options.command or command_line(options),
        "git": _git_state(),
        "started": time.strftime("%Y-%m-%dT%H:%M:%S%z", time.localtime(started)),
        "seconds": time.time() - started,
        "environment": _environment(load_start),
        "inputs": [os.fspath(p) for p in options.inputs],
        "rules": RULES,
        "shell_cm": options.shell_cm,
        "clips": [{"path": c.path, "group": c.group, "frames": c.frames, "amc_bytes": c.amc_bytes,
                   "channels": c.channels, "joints": c.joints} for c in clips],
        "runs": runs,
    }
    report["comparisons"] = compare(report)
    return report


def _tasks(options: BenchOptions) -> list[dict]:
    tasks = []
    if "mcz" in options.codecs:
        for error, rep, transform, classes, split in itertools.product(
                options.errors, options.representations, options.transforms, options.classes, options.splits):
            tasks.append({"codec": "mcz", "error_cm": float(error), "representation": rep, "transform": transform,
                          "classes": classes, "split": split})
    for codec in ("xz", "zstd"):
        if codec in options.codecs:
            tasks.append({"codec": codec})
    for codec in ("hou", "hou-shared"):
        if codec in options.codecs:
            tasks.append({"codec": codec, "errors": sorted({float(e) for e in options.errors}, reverse=True)})
    return tasks


# ----------------------------------------------------------------------------- clips


def _load_clips(sources: list[ClipSource], options: BenchOptions):
    """The clips to run on, and the `ClipReader` that reads them (and the decoded files) as the codec does."""
    from mocapzip.inputs.clip import ClipReader, clip_frame_rate

    groups = _groups(sources, options.groups, options.inputs)
    reader, clips = ClipReader(None, units=options.units), []
    for source in progress(sources, desc="read", unit="clip"):
        read = reader.motion(source)  # warnings (a dropped last frame) show once, here
        clips.append(Clip(source, groups[source.relpath], read.motion.n_frames, os.path.getsize(source.motion),
                          read.motion.values.shape[1], read.model.n_joints,
                          clip_frame_rate(read.stated_fps, DEFAULT_FPS)))
    if any(c.frames == 0 for c in clips):
        raise MocapFormatError("clip has no frames", next(c.source.motion for c in clips if c.frames == 0))
    return clips, reader


def _groups(sources: list[ClipSource], table, inputs) -> dict[str, str]:
    """Motion class of each clip for the per-class report: `table` (CSV/TSV: file, class;
    MANIFEST.tsv works), else a MANIFEST.tsv in or above an input folder, else the skeleton name."""
    fallback = {s.relpath: (s.skeleton.stem if s.skeleton is not None else "all") for s in sources}
    candidates = [Path(table)] if table else _find_manifests(inputs)
    found: dict[str, str] = {}
    for path in candidates:
        entries = read_class_table(path)
        by_file = {(path.parent / key).resolve(): value for key, value in entries.items()}
        for s in sources:
            if s.relpath in found:
                continue
            value = by_file.get(s.motion.resolve())
            if value is None:  # a table naming clips by stored path (or its tail)
                value = next((v for k, v in entries.items()
                              if k == s.relpath or k.endswith("/" + s.relpath) or s.relpath.endswith("/" + k)), None)
            if value:
                found[s.relpath] = value
    return {s.relpath: found.get(s.relpath, fallback[s.relpath]) for s in sources}


def _find_manifests(inputs) -> list[Path]:
    out = []
    for item in inputs:
        path = Path(item).resolve()
        for folder in [path if path.is_dir() else path.parent, *list((path if path.is_dir() else path.parent).parents)[:3]]:
            candidate = folder / "MANIFEST.tsv"
            if candidate.is_file() and candidate not in out:
                out.append(candidate)
                break
    return out


def _original(clip: Clip, reader):
    """(model, motion, pose) of the original clip, read again (nothing is kept between runs)."""
    from mocapzip.motion.kinematics import forward

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # already shown once when the clips were loaded
        read = reader.motion(clip.source)
    return read.model, read.motion, forward(read.model, read.motion.values, read.motion)


def _measure(clip: Clip, reader, decoded_model, decoded_motion, shell_cm: float) -> tuple[dict, np.ndarray]:
    """Errors of a decoded clip (a Motion read back from the text written) against the original;
    the worst vertex at `shell_cm` from every bone (ACL's metric) beside the joint errors."""
    from mocapzip.motion.kinematics import forward
    from mocapzip.motion.metrics import joint_distances, shell_errors, skin_error

    model, motion, pose = _original(clip, reader)
    if decoded_motion.n_frames != motion.n_frames or decoded_motion.values.shape[1] != motion.values.shape[1]:
        raise BenchError(f"decoded clip has shape {decoded_motion.values.shape}, the original {motion.values.shape}",
                         clip.source.motion)
    decoded_pose = forward(decoded_model, decoded_motion.values, decoded_motion)
    d = joint_distances(pose.positions, decoded_pose.positions)
    shell = shell_errors(model, pose, decoded_pose, shell_cm)
    return ({**_error_stats(d), "shell_error_cm": shell.worst, "shell_worst_bone": shell.worst_bone,
             "skin_error": skin_error(model, pose, decoded_pose),
             **_skate(model, pose.positions, decoded_pose.positions, clip.fps)}, d.astype(np.float32))


def _error_stats(d: np.ndarray) -> dict:
    return {"mean_error_cm": float(d.mean()), "p99_error_cm": float(np.percentile(d, 99)),
            "max_error_cm": float(d.max())}


def _skate(model, original: np.ndarray, decoded: np.ndarray, fps: float) -> dict:
    """Foot skate (`motion.contacts`): how much faster, in cm/s, the source's planted feet slide once
    decoded, at the clip's frame rate `fps`; `contact_frames` weighs it in a set's summary."""
    from mocapzip.motion.contacts import contacts, foot_skate

    planted = contacts(model, original, fps)
    return {"foot_skate_cm_s": foot_skate(original, decoded, planted, fps), "contact_frames": int(planted.sum())}


# ----------------------------------------------------------------------------- child processes


def _python_c(code: str) -> list[str]:
    """argv running `code` in a fresh interpreter that imports mocapzip from where this process did.

    Plain `python -c` puts the current directory first on sys.path: started in a repository
    checkout, the child would import the in-tree package while this process (the `mcz` script of
    an installed wheel) runs the installed one, or the reverse. Like multiprocessing's spawn, the
    child gets this process's sys.path ('' made absolute), so it always runs the same copy.
    """
    path = [entry or os.getcwd() for entry in sys.path]
    return [sys.executable, "-c", f"import sys; sys.path[:] = {path!r}\n{code}"]


def _run_child(job: dict, quiet: bool) -> dict:
    """Run one job in a fresh Python process; return its JSON answer plus its peak RSS (MB)."""
    job = {**job, "quiet": quiet}
    proc = subprocess.Popen(_python_c("from mocapzip.bench.runner import _child_main; _child_main()"),
                            stdin=subprocess.PIPE, stdout=subprocess.PIPE)
    try:
        proc.stdin.write(json.dumps(job).encode())
        proc.stdin.close()
        out = proc.stdout.read()
        proc.stdout.close()
    finally:
        _, status, usage = os.wait4(proc.pid, 0)
        proc.returncode = os.waitstatus_to_exitcode(status)
    lines = out.decode("utf-8", "replace").strip().splitlines()
    if proc.returncode != 0 or not lines:
        raise BenchError(f"benchmark step '{job['op']}' failed in its child process (exit code {proc.returncode})")
    answer = json.loads(lines[-1])
    if "error" in answer:
        raise BenchError(answer["error"])
    rss = usage.ru_maxrss / (1024 * 1024 if sys.platform == "darwin" else 1024)
    return {**answer, "peak_rss_mb": rss}


def _child_main() -> None:
    """Entry of a child process: a JSON job on stdin, a JSON answer on stdout."""
    from mocapzip import progress as progress_module

    job = json.loads(sys.stdin.read())
    progress_module.set_quiet(job.get("quiet", False))
    warnings.simplefilter("ignore")
    try:
        answer = _CHILD_OPS[job["op"]](job)
    except MocapFormatError as exc:
        answer = {"error": str(exc)}
    sys.stdout.write(json.dumps(answer) + "\n")
    sys.stdout.flush()


def _child_compress(job: dict) -> dict:
    from mocapzip import archive

    settings = archive.Settings(**job["settings"])
    start = time.perf_counter()
    summary = archive.compress(job["inputs"], job["output"], settings, asf=job["asf"], force=True, jobs=job["jobs"],
                               units=job["units"])
    return {"seconds": time.perf_counter() - start, "summary": summary}


def _child_decompress(job: dict) -> dict:
    from mocapzip import archive

    start = time.perf_counter()
    summary = archive.decompress(job["archive"], job["output"], force=True)
    return {"seconds": time.perf_counter() - start, "summary": summary}


def _child_lossless(job: dict) -> dict:
    """Compress (or decompress) each file on its own, reading and writing files as a CLI would."""
    codec, decode = job["codec"], job["decode"]
    if codec == "xz":
        encode_fn, decode_fn = (lambda b: lzma.compress(b, preset=XZ_PRESET)), lzma.decompress
    else:
        import zstandard

        compressor, decompressor = zstandard.ZstdCompressor(level=ZSTD_LEVEL), zstandard.ZstdDecompressor()
        encode_fn, decode_fn = compressor.compress, decompressor.decompress
    function = decode_fn if decode else encode_fn
    sizes = []
    start = time.perf_counter()
    for src, dst in job["files"]:
        with open(src, "rb") as fh:
            out = function(fh.read())
        with open(dst, "wb") as fh:
            fh.write(out)
        sizes.append(len(out))
    return {"seconds": time.perf_counter() - start, "sizes": sizes}


_CHILD_OPS = {"compress": _child_compress, "decompress": _child_decompress, "lossless": _child_lossless}


def run_measured(argv: list[str], env: dict | None = None, echo=None) -> dict:
    """Run a command; return its exit code, wall seconds, peak RSS (MB) and what it wrote to stderr.

    Its stdout is passed through; each stderr line also goes to `echo` (default: our stderr).
    Peak RSS is the child's `ru_maxrss` from wait4: the largest resident set of the process or of
    any worker process it waited for (forked workers share memory, so RSS is not summed).
    """
    echo = echo or (lambda line: print(line, file=sys.stderr, flush=True))
    started = time.perf_counter()
    proc = subprocess.Popen(argv, env=env, stderr=subprocess.PIPE)
    lines = []
    for raw in proc.stderr:
        line = raw.decode("utf-8", "replace").rstrip("\n")
        lines.append(line)
        echo(line)
    proc.stderr.close()
    _, status, usage = os.wait4(proc.pid, 0)
    proc.returncode = os.waitstatus_to_exitcode(status)
    return {"returncode": proc.returncode, "seconds": time.perf_counter() - started,
            "peak_rss_mb": usage.ru_maxrss / (1024 * 1024 if sys.platform == "darwin" else 1024),
            "stderr": lines}


def mcz_command() -> list[str]:
    """How to start `mcz bench` in a child process (with this interpreter, whatever PATH says)."""
    return [*_python_c("from mocapzip.cli.main import main; main()"), "bench"]


# ----------------------------------------------------------------------------- mcz


def _transform_config(name: str, wavelet: str) -> dict:
    return {"id": name, "wavelet": wavelet, "level": None} if name == "dwt" else {"id": name}


def _run_mcz(task: dict, clips: list[Clip], reader, options: BenchOptions, tmp: Path) -> dict:
    from mocapzip.archive import Archive
    from mocapzip.formats.mcz import ArchiveReader

    work = Path(tempfile.mkdtemp(dir=tmp))
    classes = task["classes"]
    if classes == CLASS_PER_CLIP:
        table = work / "classes.csv"
        table.write_text("".join(f"{c.path},{c.path}\n" for c in clips), encoding="utf-8")
        classes = os.fspath(table)
    settings = {"error_cm": task["error_cm"], "representation": task["representation"],
                "transform": _transform_config(task["transform"], options.wavelet), "classes": classes,
                "split": task["split"], "max_error_cm": max_error_cm(options.max_error, task["error_cm"]),
                "contact_error_cm": contact_error_cm(options.contact_error), "plant_feet": options.plant_feet}
    path = work / "bench.mcz"
    encoded = _run_child({"op": "compress", "inputs": [os.fspath(p) for p in options.inputs], "output": os.fspath(path),
                          "settings": settings, "asf": options.asf, "units": options.units, "jobs": options.jobs}, options.quiet)
    decoded = _run_child({"op": "decompress", "archive": os.fspath(path), "output": os.fspath(work / "out")},
                         options.quiet)
    file_size = os.path.getsize(path)
    by_path = {c.path: c for c in clips}
    rows, distances = [], {}
    with Archive(path) as opened:
        sizes = opened.stream_sizes()
        meta_rows, skeleton_names = opened.clips, [s["name"] for s in opened.meta["skeletons"]]
        coder, priors = opened.settings.coefficient_coder, opened.priors
    if sorted(r["path"] for r in meta_rows) != sorted(by_path):
        raise BenchError("the archive does not hold the clips the bench found", path)
    clip_streams = [sizes[f"clip/{i:05d}"] for i in range(len(meta_rows))]
    with ArchiveReader(path) as streams:
        parts = [_payload_parts(streams.read(f"clip/{i:05d}"), coder, priors) for i in range(len(meta_rows))]
    class_frames: dict[int, int] = {}
    for r in meta_rows:
        class_frames[r["class"]] = class_frames.get(r["class"], 0) + r["frames"]
    class_bytes = {k: sizes.get(f"class/{k:04d}", 0) for k in class_frames}
    total_frames = sum(r["frames"] for r in meta_rows)
    shared = file_size - sum(clip_streams) - sum(class_bytes.values())
    out = work / "out"
    for i, r in enumerate(progress(meta_rows, desc="measure", unit="clip")):
        clip = by_path[r["path"]]
        share = clip_streams[i] + class_bytes[r["class"]] * r["frames"] / class_frames[r["class"]] \
            + shared * r["frames"] / total_frames
        written = out / r["path"]
        in_its_file = clip.source.skeleton == clip.source.motion  # a BVH file holds its skeleton
        skeleton_file = written if in_its_file else written.parent / skeleton_names[r["skeleton"]]
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            read_back = reader.motion(ClipSource(written, skeleton_file, r["path"]))
        errors, distances[clip.path] = _measure(clip, reader, read_back.model, read_back.motion, options.shell_cm)
        basis_share = class_bytes[r["class"]] * r["frames"] / class_frames[r["class"]]
        rows.append({**_sizes(clip, share, clip_streams[i]), **parts[i], "basis_bytes": basis_share, **errors,
                     "codec_reported_error_cm": r.get("error_cm")})
    rows.sort(key=lambda row: row["path"])
    shutil_rmtree(work)
    speed = {"encode_seconds": encoded["seconds"], "decode_seconds": decoded["seconds"],
             "encode_peak_rss_mb": encoded["peak_rss_mb"], "decode_peak_rss_mb": decoded["peak_rss_mb"]}
    return _finish_run({"codec": "mcz", "label": _mcz_label(task, options), "target_error_cm": task["error_cm"],
                        "settings": {**settings, "classes": task["classes"], "jobs": options.jobs},
                        "archive_bytes": file_size, "shared_bytes": shared, "class_bytes": sum(class_bytes.values()),
                        "fixed_bytes": fixed_costs(sizes, file_size),
                        "error_measured_on": "AMC text written by mcz decompress, read back by mocapzip.formats"},
                       rows, clips, distances, speed)


def fixed_costs(sizes: dict[str, int], file_size: int) -> dict[str, int]:
    """What an archive spends besides its clips' streams (`stream_sizes`), in bytes: skeletons,
    class bases, meta, priors, and the container (the file minus every stream: HDF5's own
    structures, the index and the header). Frame patches are per clip, not fixed."""
    def total(prefix: str) -> int:
        return sum(size for name, size in sizes.items() if name == prefix or name.startswith(prefix + "/"))

    return {"skeletons": total("skeletons"), "bases": total("class"), "meta": total("meta"),
            "priors": total("priors"), "container": file_size - sum(sizes.values())}


def _payload_parts(blob: bytes, coder: str, priors) -> dict:
    """Pose and root-track bytes of a lossy clip stream (see `CodedClip.payload`).

    The context coder writes both matrices into one stream, so the pose share is the size
    of the pose matrix coded alone (with the stream's header) and the root gets the rest.
    """
    from mocapzip.codec.clip_stream import CodedClip

    try:
        coded = CodedClip.from_payload(blob, coder, priors=priors)
    except (ValueError, struct.error):
        return {"pose_bytes": None, "root_bytes": None}
    pose_bytes = len(CodedClip(coded.pose_step, coded.pose_ints, coded.root_step, None).payload(coder, priors))
    if coded.root_ints is None:
        return {"pose_bytes": len(blob), "root_bytes": 0}
    return {"pose_bytes": pose_bytes, "root_bytes": len(blob) - pose_bytes}


def shutil_rmtree(path: Path) -> None:
    import shutil

    shutil.rmtree(path, ignore_errors=True)


def _mcz_label(task: dict, options: BenchOptions | None = None) -> str:
    """The run's label; `options` give its --max-error (the no-PCA emulation, without them, has no bound)."""
    parts = [f"mcz {task['error_cm']:g} cm", task["representation"], task["transform"], f"classes {task['classes']}"]
    bound = None if options is None else max_error_cm(options.max_error, task["error_cm"])
    if bound is not None:
        parts.insert(1, f"every joint <= {bound:g} cm")
    contact = None if options is None else contact_error_cm(options.contact_error)
    if contact is not None:
        parts.insert(2 if bound is not None else 1, f"planted feet <= {contact:g} cm")
    if options is not None and options.plant_feet:
        parts.append("planted feet held")
    if task["split"]:
        parts.append("split " + ",".join(f"{s:g}" for s in task["split"]))
    return ", ".join(parts)


def _run_mcz_without_pca(task: dict, clips: list[Clip], reader, options: BenchOptions) -> dict:
    """--classes none: each clip coded with the codec's stages and an identity basis (see the module doc)."""
    from mocapzip.archive import Settings
    from mocapzip.archive.settings import chosen_representation
    from mocapzip.codec.basis import ClassBasis
    from mocapzip.codec.clip_stream import CodedClip, reconstruct
    from mocapzip.formats.amc import Motion, format_amc, parse_amc
    from mocapzip.inputs.clip import load_clips
    from mocapzip.inputs.registry import AMC
    from mocapzip.ratecontrol.encode import code_clip
    from mocapzip.representations.positions import flips_from_ranges
    from mocapzip.representations.weighted import channels_from_weighted, skeleton_params
    from mocapzip.stages import get_stage

    transform = get_stage("transform", _transform_config(task["transform"], options.wavelet))
    dead_zone, axes_from_positions = Settings().dead_zone, Settings().axes_from_positions
    used = chosen_representation(Settings(error_cm=task["error_cm"], representation=task["representation"]))
    rows, distances = [], {}
    encode_seconds = decode_seconds = 0.0
    for clip in progress(clips, desc="no PCA", unit="clip"):
        start = time.perf_counter()
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            loaded = load_clips([clip.source], used, axes_from_positions=axes_from_positions,
                                units=options.units)[0]
        basis = ClassBasis(np.zeros(loaded.poses.shape[1]), np.eye(loaded.poses.shape[1]), np.ones(loaded.poses.shape[1]))
        coding = code_clip(loaded, basis, transform, task["error_cm"], dead_zone, task["split"])
        payload, twist_flips = coding.coded.payload(), coding.twists
        n_frames = loaded.motion.n_frames
        middle = time.perf_counter()
        model, layout, representation = loaded.model, loaded.layout, loaded.representation
        poses, root = reconstruct(CodedClip.from_payload(payload), basis, transform, dead_zone, n_frames)
        params = {**skeleton_params(model, representation, layout),
                  "twist": flips_from_ranges(twist_flips, model, n_frames)}
        values = channels_from_weighted(model, representation, layout, poses, root, params, loaded.axis_weight_cm)
        m = loaded.motion
        if clip.source.format is AMC:
            text = format_amc(Motion(m.bones, m.counts, values, m.frame_numbers, m.header, clip.path))  # as decompress does
        decode_seconds += time.perf_counter() - middle
        encode_seconds += middle - start
        if clip.source.format is AMC:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                decoded = parse_amc(text.encode("latin-1", "replace"), clip.path)
        else:  # the numbers as a BVH file writes them
            decoded = replace(m, values=loaded.as_written(values))
        errors, distances[clip.path] = _measure(clip, reader, reader.skeleton(clip.source).model, decoded,
                                                options.shell_cm)
        rows.append({**_sizes(clip, len(payload), len(payload)), **_payload_parts(payload, "context", None), "basis_bytes": 0, **errors})
    settings = {"error_cm": task["error_cm"], "representation": task["representation"],
                "transform": _transform_config(task["transform"], options.wavelet), "classes": NO_PCA,
                "split": task["split"]}
    return _finish_run({"codec": "mcz", "label": _mcz_label(task), "target_error_cm": task["error_cm"],
                        "settings": settings, "archive_bytes": None,
                        "note": "no PCA: bench-only emulation with an identity basis (not an archive); bytes are "
                                "clip payloads; speeds measured in process",
                        "error_measured_on": "AMC text formatted by mocapzip.formats, read back by mocapzip.formats"},
                       rows, clips, distances,
                       {"encode_seconds": encode_seconds, "decode_seconds": decode_seconds,
                        "encode_peak_rss_mb": None, "decode_peak_rss_mb": None})


# ----------------------------------------------------------------------------- xz, zstd


def _run_lossless(codec: str, clips: list[Clip], options: BenchOptions, tmp: Path) -> dict:
    work = Path(tempfile.mkdtemp(dir=tmp))
    skeletons = sorted({c.source.skeleton for c in clips if c.source.skeleton != c.source.motion})  # BVH: in its file
    originals = [c.source.motion for c in clips] + skeletons
    packed = [work / f"{i:05d}.{codec}" for i in range(len(originals))]
    restored = [work / f"{i:05d}.out" for i in range(len(originals))]
    encoded = _run_child({"op": "lossless", "codec": codec, "decode": False,
                          "files": [[os.fspath(a), os.fspath(b)] for a, b in zip(originals, packed)]}, options.quiet)
    decoded = _run_child({"op": "lossless", "codec": codec, "decode": True,
                          "files": [[os.fspath(a), os.fspath(b)] for a, b in zip(packed, restored)]}, options.quiet)
    for a, b in zip(originals, restored):
        if Path(a).read_bytes() != Path(b).read_bytes():
            raise BenchError(f"{codec} did not restore the file byte for byte", a)
    sizes = encoded["sizes"]
    skeleton_bytes = dict(zip(skeletons, sizes[len(clips):]))
    frames_per_skeleton: dict = {}
    for c in clips:
        frames_per_skeleton[c.source.skeleton] = frames_per_skeleton.get(c.source.skeleton, 0) + c.frames
    rows = []
    for c, size in zip(clips, sizes):
        share = size + skeleton_bytes.get(c.source.skeleton, 0) * c.frames / frames_per_skeleton[c.source.skeleton]
        rows.append({**_sizes(c, share, size), "mean_error_cm": 0.0, "p99_error_cm": 0.0, "max_error_cm": 0.0,
                     "shell_error_cm": 0.0, "skin_error": 0.0, "foot_skate_cm_s": 0.0, "contact_frames": 1})
    shutil_rmtree(work)
    name = {"xz": f"xz -{XZ_PRESET}", "zstd": f"zstd -{ZSTD_LEVEL}"}[codec]
    return _finish_run({"codec": codec, "label": f"{name} (lossless, per file)", "target_error_cm": 0.0,
                        "settings": {"level": XZ_PRESET if codec == "xz" else ZSTD_LEVEL},
                        "error_measured_on": "lossless: restored files compared byte for byte"},
                       rows, clips, None,
                       {"encode_seconds": encoded["seconds"], "decode_seconds": decoded["seconds"],
                        "encode_peak_rss_mb": encoded["peak_rss_mb"], "decode_peak_rss_mb": decoded["peak_rss_mb"]})


# ----------------------------------------------------------------------------- Hou et al.


def _run_hou(targets: list[float], clips: list[Clip], reader, options: BenchOptions) -> list[dict]:
    from mocapzip.bench.baselines import hou as hou

    grid = {"grid_l": hou.GRID_L, "grid_k": hou.GRID_K, "grid_q": hou.GRID_Q, **(options.hou_grid or {})}
    chosen: dict[float, dict[str, dict]] = {t: {} for t in targets}
    search_seconds = 0.0
    for clip in progress(clips, desc="hou sweep", unit="clip"):
        _, _, pose = _original(clip, reader)
        start = time.perf_counter()
        points = hou.sweep(pose.positions, targets=targets, **grid)
        search_seconds += time.perf_counter() - start
        for t in targets:
            chosen[t][clip.path] = hou.best(points, t)
    runs = []
    for t in targets:
        rows, distances, missing = [], {}, []
        encode_seconds = decode_seconds = 0.0
        for clip in clips:
            point = chosen[t][clip.path]
            if point is None:
                missing.append(clip.path)
                continue
            params = hou.HouParams(point["L"], point["k"], point["Q"])
            start = time.perf_counter()
            positions = _original(clip, reader)[2].positions
            blob = hou.encode(positions, params)
            middle = time.perf_counter()
            decoded = hou.decode(blob)
            decode_seconds += time.perf_counter() - middle
            encode_seconds += middle - start
            d = np.linalg.norm(decoded - positions, axis=-1)
            distances[clip.path] = d.astype(np.float32)
            rows.append({**_sizes(clip, len(blob), len(blob)), **_error_stats(d), "shell_error_cm": None, "skin_error": None,
                         **_skate(reader.skeleton(clip.source).model, positions, decoded, clip.fps), "hou": params.as_dict()})
        run = _finish_run({"codec": "hou", "label": f"Hou et al. 2015, best (L, k, Q) per clip for mean error <= {t:g} cm",
                           "target_error_cm": t,
                           "settings": {"grid": {k: list(v) for k, v in grid.items()}, "basis_bits": 16,
                                        "r": "0.1 ceil(L/50)", "entropy": "mocapzip.codec.entropy.zstd.encode_ints"},
                           "search_seconds": search_seconds, "missing": missing,
                           "error_measured_on": "joint positions directly (the codec stores positions, no rotations)"},
                          rows, [c for c in clips if c.path not in missing], distances,
                          {"encode_seconds": encode_seconds, "decode_seconds": decode_seconds,
                           "encode_peak_rss_mb": None, "decode_peak_rss_mb": None})
        runs.append(run)
    return runs


def _run_hou_shared(targets: list[float], clips: list[Clip], reader, options: BenchOptions) -> list[dict]:
    from mocapzip.bench.baselines import hou as hou

    grid = {"grid_l": hou.GRID_L, "grid_k": hou.GRID_K, "grid_q": hou.GRID_Q, **(options.hou_grid or {})}
    groups: dict = {}
    for clip in clips:
        groups.setdefault(clip.source.skeleton, []).append(clip)
    rows = {t: [] for t in targets}
    distances = {t: {} for t in targets}
    missing = {t: [] for t in targets}
    seconds = {t: [0.0, 0.0] for t in targets}
    search_seconds = 0.0
    for members in progress(list(groups.values()), desc="hou-shared", unit="subject"):
        positions = [_original(c, reader)[2].positions for c in members]
        start = time.perf_counter()
        found = hou.sweep_shared(positions, targets, **grid)
        search_seconds += time.perf_counter() - start
        group_frames = sum(c.frames for c in members)
        for t in targets:
            choice = found[t]
            if choice is None:
                missing[t] += [c.path for c in members]
                continue
            start = time.perf_counter()  # the timed encode: read, forward kinematics, basis, every clip
            encoded = [_original(c, reader)[2].positions for c in members]
            basis_blob, streams = hou.encode_shared(encoded, choice["L"], choice["k"], [x["Q"] for x in choice["sequences"]])
            middle = time.perf_counter()
            basis = hou.decode_basis(basis_blob)
            decoded = [hou.decode_clip(stream, basis) for stream in streams]
            seconds[t][1] += time.perf_counter() - middle
            seconds[t][0] += middle - start
            for clip, original, stream, back, x in zip(members, encoded, streams, decoded, choice["sequences"]):
                d = np.linalg.norm(back - original, axis=-1)
                distances[t][clip.path] = d.astype(np.float32)
                share = len(stream) + len(basis_blob) * clip.frames / group_frames
                rows[t].append({**_sizes(clip, share, len(stream)), **_error_stats(d), "shell_error_cm": None, "skin_error": None,
                                **_skate(reader.skeleton(clip.source).model, original, back, clip.fps),
                                "basis_bytes": len(basis_blob) * clip.frames / group_frames,
                                "hou": {"L": choice["L"], "k": choice["k"], "Q": x["Q"]}})
    runs = []
    for t in targets:
        kept = [c for c in clips if c.path not in missing[t]]
        rows[t].sort(key=lambda r: r["path"])
        runs.append(_finish_run(
            {"codec": "hou-shared", "label": f"Hou et al. 2015, one basis per subject, mean error <= {t:g} cm",
             "target_error_cm": t,
             "settings": {"grid": {k: list(v) for k, v in grid.items()}, "basis_bits": 16, "groups": "subject",
                          "r": "0.1 ceil(L/50)", "entropy": "mocapzip.codec.entropy.zstd.encode_ints"},
             "search_seconds": search_seconds, "missing": missing[t],
             "error_measured_on": "joint positions directly (the codec stores positions, no rotations)"},
            rows[t], kept, distances[t],
            {"encode_seconds": seconds[t][0], "decode_seconds": seconds[t][1],
             "encode_peak_rss_mb": None, "decode_peak_rss_mb": None}))
    return runs


# ----------------------------------------------------------------------------- aggregation


def _sizes(clip: Clip, share: float, payload: int) -> dict:
    return {"path": clip.path, "group": clip.group, "frames": clip.frames, "bytes": share, "payload_bytes": payload,
            "bytes_per_frame": share / clip.frames, "payload_bytes_per_frame": payload / clip.frames,
            "ratio_amc": clip.amc_bytes / share, "ratio_f32_channels": clip.f32_channel_bytes / share,
            "ratio_f32_positions": clip.f32_position_bytes / share}


def _summary(rows: list[dict], clips: list[Clip], distances: dict | None) -> dict:
    by_path = {c.path: c for c in clips}
    members = [by_path[r["path"]] for r in rows]
    frames = sum(c.frames for c in members)
    size = sum(r["bytes"] for r in rows)
    payload = sum(r["payload_bytes"] for r in rows)
    out = {"clips": len(rows), "frames": frames, "bytes": size, "payload_bytes": payload,
           "bytes_per_frame": size / frames, "payload_bytes_per_frame": payload / frames,
           "amc_bytes": sum(c.amc_bytes for c in members),
           "ratio_amc": sum(c.amc_bytes for c in members) / size,
           "ratio_f32_channels": sum(c.f32_channel_bytes for c in members) / size,
           "ratio_f32_positions": sum(c.f32_position_bytes for c in members) / size}
    for key in ("pose_bytes", "root_bytes", "basis_bytes"):
        if rows and all(r.get(key) is not None for r in rows):
            out[key] = sum(r[key] for r in rows)
            out[key + "_per_frame"] = out[key] / frames
    weights = np.array([c.frames * c.joints for c in members], dtype=float)
    out["mean_error_cm"] = float(np.dot([r["mean_error_cm"] for r in rows], weights) / weights.sum())
    if distances:
        d = np.concatenate([distances[r["path"]].ravel() for r in rows])
        out["p99_error_cm"] = float(np.percentile(d, 99))
    else:
        out["p99_error_cm"] = max(r["p99_error_cm"] for r in rows)
    out["max_error_cm"] = max(r["max_error_cm"] for r in rows)
    shells = [r.get("shell_error_cm") for r in rows]
    out["shell_error_cm"] = max(shells) if all(s is not None for s in shells) else None
    contact = [r.get("contact_frames", 0) for r in rows]
    if sum(contact) and all("foot_skate_cm_s" in r for r in rows):
        out["foot_skate_cm_s"] = float(np.dot([r["foot_skate_cm_s"] for r in rows], contact) / sum(contact))
    skins = [r["skin_error"] for r in rows]
    out["skin_error"] = (float(np.dot(skins, [c.frames for c in members]) / frames)
                         if all(s is not None for s in skins) else None)
    out["worst_clip_mean_error_cm"] = max(r["mean_error_cm"] for r in rows)
    return out


def _finish_run(run: dict, rows: list[dict], clips: list[Clip], distances, speed: dict) -> dict:
    if not rows:
        run.update(overall=None, classes={}, clips=[])
        return run
    overall = _summary(rows, clips, distances)
    frames = overall["frames"]
    overall["encode_seconds"], overall["decode_seconds"] = speed["encode_seconds"], speed["decode_seconds"]
    overall["encode_fps"] = frames / speed["encode_seconds"] if speed["encode_seconds"] else None
    overall["decode_fps"] = frames / speed["decode_seconds"] if speed["decode_seconds"] else None
    overall["encode_peak_rss_mb"], overall["decode_peak_rss_mb"] = speed["encode_peak_rss_mb"], speed["decode_peak_rss_mb"]
    groups = sorted({r["group"] for r in rows})
    run["overall"] = overall
    run["classes"] = {g: _summary([r for r in rows if r["group"] == g], clips, distances) for g in groups}
    run["clips"] = rows
    return run


def compare(report: dict) -> list[dict]:
    """Per target error: mcz bytes / Hou bytes per clip (median, worst), and mcz speed vs xz -9."""
    runs = report["runs"]
    xz = next((r for r in runs if r["codec"] == "xz" and r["overall"]), None)
    out = []
    for run in runs:
        if run["codec"] != "mcz" or not run["overall"]:
            continue
        entry = {"mcz": run["label"], "target_error_cm": run["target_error_cm"]}
        for codec, key in (("hou", "mcz_over_hou_bytes"), ("hou-shared", "mcz_over_hou_shared_bytes")):
            hou_run = next((r for r in runs if r["codec"] == codec and r["target_error_cm"] == run["target_error_cm"]
                            and r["overall"]), None)
            if not hou_run:
                continue
            hou_bytes = {c["path"]: c["bytes"] for c in hou_run["clips"]}
            ratios = sorted((c["bytes"] / hou_bytes[c["path"]], c["path"]) for c in run["clips"] if c["path"] in hou_bytes)
            values = np.array([r for r, _ in ratios])
            entry[key] = {
                "clips": len(ratios), "median": float(np.median(values)), "worst": ratios[-1][0],
                "worst_clip": ratios[-1][1], "best": ratios[0][0], "best_clip": ratios[0][1],
                "mcz_smaller_in": int((values < 1).sum()),
                "overall": run["overall"]["bytes"] / sum(hou_bytes[p] for _, p in ratios)
                if len(ratios) == len(run["clips"]) else None}
        if xz:
            o, x = run["overall"], xz["overall"]
            entry["vs_xz"] = {
                "bytes": o["bytes"] / x["bytes"],
                "encode_speed": (o["encode_fps"] / x["encode_fps"]) if o["encode_fps"] and x["encode_fps"] else None,
                "decode_speed": (o["decode_fps"] / x["decode_fps"]) if o["decode_fps"] and x["decode_fps"] else None}
        out.append(entry)
    return out


# ----------------------------------------------------------------------------- environment


def _git_state() -> dict | None:
    root = Path(__file__).resolve().parents[2]
    try:
        head = subprocess.run(["git", "rev-parse", "HEAD"], cwd=root, capture_output=True, text=True, timeout=10)
        dirty = subprocess.run(["git", "status", "--porcelain", "--untracked-files=no"], cwd=root,
                               capture_output=True, text=True, timeout=10)
    except (OSError, subprocess.SubprocessError):
        return None
    if head.returncode != 0:
        return None
    return {"commit": head.stdout.strip(), "uncommitted_changes": bool(dirty.stdout.strip())}


def _environment(load_start) -> dict:
    import scipy

    return {"python": platform.python_version(), "numpy": np.__version__, "scipy": scipy.__version__,
            "platform": platform.platform(), "cpus": os.cpu_count(),
            "load_average_start": list(load_start) if load_start else None,
            "load_average_end": list(os.getloadavg()) if hasattr(os, "getloadavg") else None,
            "blas_threads": {k: os.environ.get(k) for k in BLAS_THREAD_VARIABLES}}


def command_line(options: BenchOptions) -> str:
    """The `mcz bench` command that runs `options` (for reports: how to get these numbers again)."""
    import shlex

    args = ["mcz", "bench", *map(os.fspath, options.inputs)]
    for flag, values, default in (("-e", [f"{e:g}" for e in options.errors], ["1"]),
                                  ("-r", options.representations, [AUTO_REPRESENTATION]),
                                  ("-t", options.transforms, ["dct-edges"]), ("-c", options.classes, ["pooled"]),
                                  ("--split", [",".join(f"{x:g}" for x in s) for s in options.splits if s], [])):
        if list(values) != default:
            for v in values:
                args += [flag, v]
    if list(options.codecs) != list(CODECS):
        args += ["--codec", ",".join(options.codecs)]
    for flag, bound in (("--max-error", options.max_error), ("--contact-error", options.contact_error)):
        if bound is not None:
            args += [flag, "none" if bound == "none" else f"{bound:g}"]
    if options.plant_feet:
        args.append("--plant-feet")
    if options.shell_cm != ACL_SHELL_CM:
        args += ["--shell-cm", f"{options.shell_cm:g}"]
    if "dwt" in options.transforms and options.wavelet != "db4":
        args += ["--wavelet", options.wavelet]
    for flag, value in (("--groups", options.groups), ("--asf", options.asf)):
        if value:
            args += [flag, os.fspath(value)]
    args += ["-j", str(options.jobs)]
    return shlex.join(args)
