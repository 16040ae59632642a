"""mcz beside ACL (the Animation Compression Library, Unreal Engine's animation codec), both
scored by ACL's own error metric: virtual vertices 3 cm from every bone, in object space.

    python benchmarks/acl.py --acl-compressor BUILD/acl_compressor [--fps 24|120] [--clips N]
        [--data cmu|bandai|DIR] [--runs E:MAX[:VERTEX[:REPRESENTATION]],...] [--acl-precision CM,...] [-j N] [--keep DIR]

Never run in CI: ACL is built by hand, once (nfrechette/acl, MIT; v2.1.0 is the release the
figures in docs/acl.md come from). Its top-level CMake also builds its unit tests, which need
the catch2 submodule, so benchmarks/acl_build/CMakeLists.txt builds only `tools/acl_compressor`
and `acl_error` (benchmarks/acl_build/acl_error.cpp: ACL's own error of a decode, and the
decoded samples, which acl_compressor cannot write), with ACL's compiler settings:

    git clone https://github.com/nfrechette/acl /tmp/acl && git -C /tmp/acl checkout v2.1.0
    git -C /tmp/acl submodule update --init external/rtm external/sjson-cpp
    cmake -S benchmarks/acl_build -B /tmp/acl-build -DACL_DIR=/tmp/acl -DCMAKE_BUILD_TYPE=Release -DCPU_INSTRUCTION_SET=x64
    make -C /tmp/acl-build -j2          # writes /tmp/acl-build/acl_compressor and /tmp/acl-build/acl_error

What it does, on N clips spread over the data set (CMU ASF/AMC at 120 fps, Bandai BVH at 30):
1. At `--fps` (a divisor of the clips' rate: every 5th frame of CMU for 24 fps) it writes the
   clips' frames as ASF/AMC or BVH files, which mcz compresses, and exports the same clips as ACL
   raw clips (`.acl.sjson`, version 5, binary exact float32): one transform per bone of mcz's
   skeleton model at its start, plus one at every leaf's end (`metrics.shell_bones`), units cm,
   bind pose the model's base pose, shell distance 3 cm, precision `--acl-precision` (ACL's
   default 0.01 cm). ACL's forward kinematics of the export is checked against mcz's own.
2. ACL: `acl_compressor -acl=CLIP -stats=...` at its default settings for the size (its
   compressed track list without names, as a game ships it) and its own max error (against the
   raw clip after its pre-processing), then `-out=CLIP.acl`, decoded by `acl_error`.
3. mcz: `mocapzip.compress` of the clips at each `-e:--max-error` pair of `--runs`, the archive's
   bytes (skeletons and container included), decompressed as `mcz decompress` writes the files.
4. Every decode, ACL's and mcz's, is scored by `mocapzip.motion.metrics.shell_errors` against the
   source clip's frames; ACL's C++ metric (`acl_error`) scores the same pairs, and the largest
   difference between the two is printed: the table means something only where they agree.

Prints a markdown table: bytes, bytes per second of motion, bytes against ACL's default, the
worst vertex error (ACL's max error), the median clip's worst, the worst joint error and the mean,
and the bone most often worst.
"""

from __future__ import annotations

import os

from mocapzip.defaults import BLAS_THREAD_VARIABLES  # imports nothing: numpy is not loaded yet

for _var in BLAS_THREAD_VARIABLES:  # before numpy: as `mcz` runs (cli/__init__.py)
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import dataclasses  # noqa: E402
import json  # noqa: E402
import re  # noqa: E402
import shutil  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from collections import Counter  # noqa: E402
from pathlib import Path  # noqa: E402
from typing import NamedTuple  # noqa: E402

import numpy as np  # noqa: E402
from scipy.spatial.transform import Rotation  # noqa: E402

import mocapzip  # noqa: E402
from mocapzip.defaults import ACL_SHELL_CM, DEFAULT_FPS  # noqa: E402
from mocapzip.formats.amc import read_amc, write_amc  # noqa: E402
from mocapzip.formats.bvh import read_bvh, write_bvh  # noqa: E402
from mocapzip.inputs.clip import ClipReader  # noqa: E402
from mocapzip.inputs.discover import ClipSource, find_clips  # noqa: E402
from mocapzip.inputs.registry import BVH  # noqa: E402
from mocapzip.motion.kinematics import Pose, forward  # noqa: E402
from mocapzip.motion.metrics import joint_distances, shell_bones, shell_frames, shell_vertex_errors  # noqa: E402
from mocapzip.motion.skeleton import SkeletonModel  # noqa: E402

DATA = Path(__file__).resolve().parents[2] / "shared" / "data"
SETS = {"cmu": DATA / "cmu", "bandai": DATA / "bvh-bandai"}
RUNS = "1:10,0.1:1,0.01:0.05,0.002:0.01,0.001:0.005"
ACL_PRECISION_CM = 0.01  # ACL's default precision (`track_desc_transformf::precision`, in cm as Unreal's)
EXPORT_TOLERANCE_CM = 1e-3  # ACL's kinematics of the float32 export against mcz's (float32: ~1e-5 cm)
AGREEMENT_CM = 1e-3  # the two metrics' largest difference beyond which the table means nothing


class Posed(NamedTuple):
    """A clip as the metric takes it: its skeleton model, its forward kinematics, its frame rate."""

    model: SkeletonModel
    pose: Pose
    fps: float


class AclClip(NamedTuple):
    """A clip as ACL's raw transform tracks (local space, float32, rotations x y z w)."""

    names: tuple[str, ...]
    parents: np.ndarray  # (B,) -1 for the root
    rotations: np.ndarray  # (F, B, 4)
    translations: np.ndarray  # (F, B, 3) cm
    bind_translations: np.ndarray  # (B, 3) cm: the base pose's, ACL's default value of each track


class Score(NamedTuple):
    """One codec setting over all clips."""

    label: str
    setting: str
    bytes: int
    clips: list  # a ClipScore per clip
    seconds: float  # compressing
    agreement: float  # largest |mcz's metric - ACL's C++ metric| over the clips (cm)
    own_error: float | None = None  # ACL's max error as its stats report it


def read_posed(folder: Path, fps: float | None = None) -> dict[str, Posed]:
    """Every clip under `folder` by its relative path, read as mcz reads it (a BVH clip in its
    model's channels), at `fps` or the rate its files state (CMU's AMC state none: 120)."""
    reader = ClipReader(None)
    posed = {}
    for source in find_clips([folder]):
        read = reader.motion(source)
        rate = fps or read.stated_fps or DEFAULT_FPS
        posed[source.relpath] = Posed(read.model, forward(read.model, read.motion.values, read.motion), rate)
    return posed


def pick(data: Path, count: int) -> list[ClipSource]:
    """`count` clips spread evenly over the data set's sorted clips (all of them if it has fewer)."""
    clips = find_clips([data])
    if count >= len(clips):
        return clips
    return [clips[i] for i in np.unique(np.linspace(0, len(clips) - 1, count).round().astype(int))]


def write_inputs(clips: list[ClipSource], data: Path, step: int, folder: Path) -> None:
    """The clips' files under `folder` as under `data`, every `step`th frame (an AMC's skeleton
    beside it), the files mcz compresses and the metric reads as the source."""
    for source in clips:
        target = folder / source.relpath
        target.parent.mkdir(parents=True, exist_ok=True)
        if source.format is BVH:
            bvh = read_bvh(source.motion)
            write_bvh(dataclasses.replace(bvh, values=bvh.values[::step], frame_time=bvh.frame_time * step,
                                          frames_text=None), target)
            continue
        shutil.copyfile(source.skeleton, folder / source.skeleton.relative_to(data))
        motion = read_amc(source.motion)
        kept = motion.values[::step]
        write_amc(dataclasses.replace(motion, values=kept, frame_numbers=np.arange(1, len(kept) + 1)), target,
                  style=motion.style)


def acl_tracks(posed: Posed) -> AclClip:
    """The clip's `shell_bones` frames as ACL's local transforms: each frame's rotation relative to
    its parent's, and its origin's offset in its parent's frame, which on mcz's rigid bones is the
    parent bone's vector (the root: its world position)."""
    bones = shell_bones(posed.model)
    world = posed.pose.rotations[:, bones.rotation_of]  # (F, B, 3, 3), rows: the frame's axes
    parent_world = world[:, np.maximum(bones.parents, 0)]
    parent_world[:, bones.parents < 0] = np.eye(3)
    local = parent_world @ np.swapaxes(world, -1, -2)  # the column-vector matrix of R_b R_parent^T
    quats = Rotation.from_matrix(local.reshape(-1, 3, 3)).as_quat().reshape(*local.shape[:2], 4)
    quats *= np.where(quats[..., 3:] < 0, -1.0, 1.0)  # w >= 0, as ACL stores rotations
    offsets = posed.model.offsets[bones.origin_at]
    offsets[bones.parents < 0] = 0.0
    translations = np.repeat(offsets[None], len(world), axis=0)
    translations[:, bones.parents < 0] = posed.pose.positions[:, :1]
    return AclClip(bones.names, bones.parents, quats.astype(np.float32), translations.astype(np.float32),
                   offsets.astype(np.float32))


def acl_object_frames(parents: np.ndarray, rotations: np.ndarray, translations: np.ndarray):
    """((F, B, 3, 3) axes, (F, B, 3) origins) of local transforms put together as ACL does
    (object = parent * local, `qvvf_transform_error_metric::local_to_object_space`), in float64."""
    local = Rotation.from_quat(rotations.reshape(-1, 4).astype(np.float64)).as_matrix()
    local = local.reshape(*rotations.shape[:2], 3, 3)
    rotation, origin = np.empty_like(local), np.empty(translations.shape)
    for b, p in enumerate(parents):  # parents come before their children
        if p < 0:
            rotation[:, b], origin[:, b] = local[:, b], translations[:, b]
        else:
            rotation[:, b] = rotation[:, p] @ local[:, b]
            origin[:, b] = origin[:, p] + np.einsum("fij,fj->fi", rotation[:, p], translations[:, b])
    return np.swapaxes(rotation, -1, -2), origin


def _hex(values) -> list[str]:
    return [f'"{v:08X}"' for v in np.asarray(values, dtype=np.float32).view(np.uint32).ravel()]


def write_acl_clip(path: Path, name: str, clip: AclClip, fps: float, precision_cm: float) -> None:
    """`clip` as ACL's raw track list (what its `clip_writer.h` writes, version 5, binary exact)."""
    sample = '\t\t\t[ [ "%08X", "%08X", "%08X", "%08X" ], [ "%08X", "%08X", "%08X" ], [ "3F800000", "3F800000", "3F800000" ] ]\n'
    bits = np.concatenate([clip.rotations, clip.translations], axis=-1).view(np.uint32)  # (F, B, 7)
    with open(path, "w") as out:
        out.write(f'version = 5\n\ntrack_list = {{\n\tname = "{name}"\n\tnum_samples = {bits.shape[0]}\n'
                  f"\tsample_rate = {fps:g}\n\tis_binary_exact = true\n}}\n\ntracks = [\n")
        for b, track in enumerate(clip.names):
            out.write(f'\t{{\n\t\tname = "{track}"\n\t\ttype = "qvvf"\n\t\tprecision = {_hex(precision_cm)[0]}\n')
            if clip.parents[b] >= 0:  # ACL's reader takes the keys in its order
                out.write(f"\t\tparent_index = {clip.parents[b]}\n")
            out.write(f"\t\tshell_distance = {_hex(ACL_SHELL_CM)[0]}\n"
                      f"\t\tbind_rotation = [ {', '.join(_hex([0, 0, 0, 1]))} ]\n"
                      f"\t\tbind_translation = [ {', '.join(_hex(clip.bind_translations[b]))} ]\n"
                      f"\t\tbind_scale = [ {', '.join(_hex([1, 1, 1]))} ]\n\t\tdata = [\n")
            out.write("".join(sample % tuple(row) for row in bits[:, b].tolist()))
            out.write("\t\t]\n\t}\n")
        out.write("]\n")


def acl_error(tool: Path, raw: Path, other: Path, samples: Path | None = None) -> dict:
    """ACL's own error of `other` (a compressed `.acl` or a raw `.acl.sjson`) against `raw`."""
    command = [str(tool), str(raw), str(other)] + ([str(samples)] if samples else [])
    return json.loads(subprocess.run(command, check=True, capture_output=True, text=True).stdout)


class AclRun(NamedTuple):
    """acl_compressor at its default settings on one raw clip."""

    size: int  # bytes of the compressed track list (no names: as a game ships it)
    own_error: float  # its max error, against the raw clip after its pre-processing (cm)
    seconds: float  # its compression time
    error: float  # ACL's error against the raw clip as it is (`acl_error`, cm)
    decoded: np.ndarray  # (F, B, 10) the decoded samples: rotation x y z w, translation, scale


def run_acl(compressor: Path, error_tool: Path, raw: Path, work: Path) -> AclRun:
    stats, compressed, samples = work / f"{raw.stem}.stats.sjson", work / f"{raw.stem}.acl", work / f"{raw.stem}.f32"
    subprocess.run([str(compressor), f"-acl={raw}", f"-stats={stats}"], check=True, capture_output=True)
    text = stats.read_text()
    size, own, seconds = (float(re.search(rf"\b{key} = ([-+0-9.eE]+)", text).group(1))
                          for key in ("compressed_size", "max_error", "compression_time"))
    subprocess.run([str(compressor), f"-acl={raw}", f"-out={compressed}"], check=True, capture_output=True)
    measured = acl_error(error_tool, raw, compressed, samples)
    decoded = np.fromfile(samples, dtype=np.float32).reshape(measured["num_samples"], measured["num_tracks"], 10)
    return AclRun(int(size), own, seconds, measured["max_error"], decoded)


class Exported(NamedTuple):
    """A source clip as ACL takes it: its raw clip file and the frames ACL's kinematics gives it."""

    raw: Path
    tracks: AclClip
    axes: np.ndarray
    origins: np.ndarray
    miss: float  # how far ACL's kinematics of the export is from mcz's joints and axes (cm)


def export_sources(sources: dict[str, Posed], folder: Path, precision_cm: float) -> dict[str, Exported]:
    """Every source clip as an ACL raw clip in `folder`; exits if ACL's kinematics of the export
    misses mcz's joints or axes by more than EXPORT_TOLERANCE_CM."""
    exported = {}
    for name, posed in sources.items():
        tracks = acl_tracks(posed)
        path = folder / f"{_file_name(name)}.acl.sjson"
        write_acl_clip(path, name, tracks, posed.fps, precision_cm)
        axes, origins = acl_object_frames(tracks.parents, tracks.rotations, tracks.translations)
        want_axes, want_origins = shell_frames(posed.model, posed.pose)
        miss = max(np.abs(origins - want_origins).max(), ACL_SHELL_CM * np.abs(axes - want_axes).max())
        if miss > EXPORT_TOLERANCE_CM:
            sys.exit(f"{name}: ACL's kinematics of the export misses mcz's by {miss:.3g} cm")
        exported[name] = Exported(path, tracks, axes, origins, miss)
    return exported


def _file_name(relpath: str) -> str:
    return relpath.replace("/", "_").rsplit(".", 1)[0]


class ClipScore(NamedTuple):
    """A decode of one clip against its source (cm)."""

    vertex: float  # the worst shell vertex: ACL's max error
    worst_bone: str  # whose vertex that is
    joint_max: float
    joint_mean: float


def score_clip(posed: Posed, axes: np.ndarray, origins: np.ndarray) -> ClipScore:
    """The decoded `shell_bones` frames (`axes`, `origins`) of a clip against its source `posed`."""
    bones = shell_bones(posed.model)
    errors = shell_vertex_errors(*shell_frames(posed.model, posed.pose), axes, origins)
    first = np.unique(bones.origin_at, return_index=True)[1]  # every joint is a frame's origin
    distances = joint_distances(posed.pose.positions, origins[:, first])
    return ClipScore(float(errors.max()), bones.names[int(errors.max(axis=0).argmax())], float(distances.max()),
                     float(distances.mean()))


def score_acl(args, sources, exported, work: Path, precision_cm: float) -> Score:
    """ACL at its default settings (and the tracks' `precision_cm`) on every clip."""
    total, seconds, agreement, own, clips = 0, 0.0, 0.0, 0.0, []
    for name, clip in exported.items():
        run = run_acl(args.acl_compressor, args.acl_error, clip.raw, work)
        axes, origins = acl_object_frames(clip.tracks.parents, run.decoded[..., :4], run.decoded[..., 4:7])
        # ACL's C++ metric measured the decode against the float32 export: so does this one
        agreement = max(agreement, abs(shell_vertex_errors(clip.axes, clip.origins, axes, origins).max() - run.error))
        clips.append(score_clip(sources[name], axes, origins))
        total, seconds, own = total + run.size, seconds + run.seconds, max(own, run.own_error)
    return Score("ACL 2.1", f"defaults, precision {precision_cm:g} cm", total, clips, seconds, agreement, own)


def score_mcz(args, sources, exported, inputs: Path, work: Path, mean_cm: float, max_cm: float | None,
              vertex_cm: float | None = None, representation: str | None = None) -> Score:
    """mcz at `-e mean_cm --max-error max_cm [--max-vertex-error vertex_cm] [-r representation]` on the
    clips under `inputs`, decoded as written."""
    archive, decoded_dir = work / "set.mcz", work / "decoded"
    shutil.rmtree(decoded_dir, ignore_errors=True)
    options = {"fps": args.fps} if args.fps else {}
    started = time.perf_counter()
    if vertex_cm is not None:
        options["max_vertex_error"] = vertex_cm
    if representation is not None:
        options["representation"] = representation
    summary = mocapzip.compress(inputs, archive, error=mean_cm, max_error=max_cm, jobs=args.jobs, force=True, **options)
    seconds = time.perf_counter() - started
    mocapzip.decompress(archive, decoded_dir)
    decoded = read_posed(decoded_dir, args.fps)
    clips, agreement = [], 0.0
    for name, posed in sources.items():
        back = decoded[name]
        clips.append(score_clip(posed, *shell_frames(back.model, back.pose)))
        # the same decode exported and scored by ACL's C++ metric against the source's export
        tracks = acl_tracks(back)
        path = work / f"{_file_name(name)}.mcz.acl.sjson"
        write_acl_clip(path, name, tracks, back.fps, ACL_PRECISION_CM)
        cpp_error = acl_error(args.acl_error, exported[name].raw, path)["max_error"]
        ours = shell_vertex_errors(exported[name].axes, exported[name].origins,
                                   *acl_object_frames(tracks.parents, tracks.rotations, tracks.translations)).max()
        agreement = max(agreement, abs(ours - cpp_error))
        path.unlink()
    setting = f"-e {mean_cm:g} --max-error {'none' if max_cm is None else f'{max_cm:g}'}"
    setting += "" if vertex_cm is None else f" --max-vertex-error {vertex_cm:.4g}"
    with mocapzip.open(archive) as opened:  # the default ("auto") or the one given, as the archive stores it
        used = opened.settings.representation
    setting += f" -r {used}" if representation not in (None, "auto") else f" (-r auto: {used})"
    return Score("mcz", setting, summary["output_bytes"], clips, seconds, agreement)


def read_posed_rate(clips: list[ClipSource]) -> float:
    """The frame rate all `clips` share (their files' or 120), or exit."""
    reader = ClipReader(None)
    rates = {reader.motion(c).stated_fps or DEFAULT_FPS for c in clips}
    if len(rates) != 1:
        sys.exit(f"the clips have different frame rates: {sorted(rates)}")
    return rates.pop()


def table(scores: list[Score], seconds_of_motion: float, reference: Score) -> str:
    """The markdown table of `scores`, bytes also against `reference`'s; "mean joint" is the clips'
    mean of their mean joint error."""
    rows = ["| codec | setting | bytes | B/s of motion | × ACL | worst vertex (cm) | median clip's worst vertex | "
            "worst joint (cm) | mean joint (cm) | bone most often worst | seconds | metric agreement (cm) |",
            "|---|---|---:|---:|---:|---:|---:|---:|---:|---|---:|---:|"]
    for s in scores:
        vertex = [c.vertex for c in s.clips]
        (bone, times), = Counter(c.worst_bone for c in s.clips).most_common(1)
        rows.append(f"| {s.label} | {s.setting} | {s.bytes:,} | {s.bytes / seconds_of_motion:,.0f} | "
                    f"{s.bytes / reference.bytes:.2f} | {max(vertex):.4f} | {np.median(vertex):.4f} | "
                    f"{max(c.joint_max for c in s.clips):.4f} | {np.mean([c.joint_mean for c in s.clips]):.4f} | "
                    f"{bone} ({times}/{len(s.clips)}) | {s.seconds:.1f} | {s.agreement:.1e} |")
    return "\n".join(rows)


def at_acl_error(acl: Score, mcz: list[Score]) -> str:
    """What mcz needs for ACL's worst vertex error: its bytes against ACL's, interpolated (log bytes
    against log error) between the two mcz settings, next in size, whose worst errors bracket it;
    or the nearest setting, where none reaches it."""
    target = max(c.vertex for c in acl.clips)
    runs = sorted(((s.bytes, max(c.vertex for c in s.clips), s.setting) for s in mcz))
    for (small, loose, _), (large, tight, _) in zip(runs, runs[1:]):
        if tight <= target <= loose:
            share = np.log(loose / target) / np.log(loose / tight) if loose > tight else 1.0
            return f"{np.exp(np.log(small) + share * np.log(large / small)) / acl.bytes:.2f}× ACL's bytes"
    size, error, setting = min(runs, key=lambda run: abs(np.log(run[1] / target)))
    return (f"not reached by these settings; the nearest, `{setting}`, takes {size / acl.bytes:.2f}× ACL's bytes "
            f"for {error / target:.2f}× its error")


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--acl-compressor", type=Path, required=True, help="ACL's tools/acl_compressor, built")
    parser.add_argument("--acl-error", type=Path, help="benchmarks/acl_build's acl_error (default: beside acl_compressor)")
    parser.add_argument("--data", default="cmu", help="cmu, bandai or a folder of ASF/AMC or BVH clips")
    parser.add_argument("--fps", type=float, help="frame rate to sample the clips at (a divisor of theirs; default theirs)")
    parser.add_argument("--clips", type=int, default=4, help="clips spread over the data set (default 4)")
    parser.add_argument("--runs", default=RUNS, help="mcz's comma-separated -e:--max-error[:--max-vertex-error[:-r]] "
                        "settings (MAX 'none': no bound on joints; VERTEX 'acl': ACL's worst vertex at its first "
                        "precision, '' none; -r a representation, e.g. channels; none: auto, mcz's default)")
    parser.add_argument("--acl-precision", default=str(ACL_PRECISION_CM), help="ACL's comma-separated precisions (cm)")
    parser.add_argument("-j", "--jobs", type=int, default=1)
    parser.add_argument("--keep", type=Path, help="write the clips, ACL files and archives here and keep them")
    args = parser.parse_args(argv)
    args.acl_error = args.acl_error or args.acl_compressor.with_name("acl_error")
    for tool in (args.acl_compressor, args.acl_error):
        if not os.access(tool, os.X_OK):
            parser.error(f"{tool} is not an executable (build it as this script's docstring says)")
    data = SETS.get(args.data, Path(args.data))
    clips = pick(data, args.clips)
    with tempfile.TemporaryDirectory() as scratch:
        work = args.keep or Path(scratch)
        inputs, acl_dir = work / "clips", work / "acl"
        for folder in (inputs, acl_dir):
            folder.mkdir(parents=True, exist_ok=True)
        rate = read_posed_rate(clips)
        step = 1 if not args.fps else int(round(rate / args.fps))
        if step < 1 or abs(rate / step - (args.fps or rate)) > 1e-6:
            parser.error(f"--fps {args.fps:g} does not divide the clips' {rate:g} fps")
        write_inputs(clips, data, step, inputs)
        sources = read_posed(inputs, args.fps)
        seconds = sum(len(p.pose.positions) / p.fps for p in sources.values())
        frames = sum(len(p.pose.positions) for p in sources.values())
        load = os.getloadavg()[0]
        scores = []
        for precision in (float(p) for p in args.acl_precision.split(",")):
            exported = export_sources(sources, acl_dir, precision)
            scores.append(score_acl(args, sources, exported, acl_dir, precision))
            print(f"ACL at {precision:g} cm: {scores[-1].bytes:,} bytes", file=sys.stderr, flush=True)
        exported = export_sources(sources, acl_dir, ACL_PRECISION_CM)
        for run in args.runs.split(","):
            mean_text, max_text, *rest = run.split(":")
            vertex_text, representation = (rest + ["", ""])[:2]
            vertex = None
            if vertex_text:  # "acl": ACL's own worst vertex at its first precision, so both meet the same bound
                vertex = max(c.vertex for c in scores[0].clips) if vertex_text == "acl" else float(vertex_text)
            scores.append(score_mcz(args, sources, exported, inputs, work, float(mean_text),
                                    None if max_text == "none" else float(max_text), vertex, representation or None))
            print(f"mcz {scores[-1].setting}: {scores[-1].bytes:,} bytes", file=sys.stderr, flush=True)
    print(f"`python benchmarks/acl.py {' '.join(sys.argv[1:] if argv is None else argv)}`: {len(sources)} clips, {frames:,} frames, "
          f"{seconds:.1f} s of motion at {sources[next(iter(sources))].fps:g} fps; {os.cpu_count()} CPUs, "
          f"load average {load:.1f} at start, {os.getloadavg()[0]:.1f} at end. ACL's kinematics of the export "
          f"is within {max(e.miss for e in exported.values()):.1e} cm of mcz's. ACL's own max error (against its "
          f"pre-processed raw clip): {', '.join(f'{s.own_error:.4f}' for s in scores if s.own_error is not None)} cm.\n")
    print(table(scores, seconds, scores[0]))
    mcz = [s for s in scores if s.own_error is None]
    for acl in (s for s in scores if s.own_error is not None):
        print(f"\nmcz at ACL's worst vertex error with {acl.setting} ({max(c.vertex for c in acl.clips):.4f} cm): "
              f"{at_acl_error(acl, mcz)}.")
    if max(s.agreement for s in scores) > AGREEMENT_CM:
        print(f"\n**The two metrics disagree by more than {AGREEMENT_CM:g} cm: these figures mean nothing.**")


if __name__ == "__main__":
    main()
