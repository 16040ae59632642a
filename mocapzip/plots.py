"""`mcz plot` and `mcz view`: an archive's errors against its source, and its clips, as pictures.

Optional (`pip install 'mocapzip[plot]'`): matplotlib is imported inside these functions only,
so the core install stays lean. Everything is measured through the API, as a user would: the
decoded clip's `positions()` against `joint_positions` / `bvh_joint_positions` of the file it
was compressed from. Every file is drawn whole in memory, then written atomically: a failure
leaves nothing behind.
"""

from __future__ import annotations

import io
import math
import os
import re
import tempfile
import warnings
from pathlib import Path

import numpy as np

import mocapzip
from mocapzip.formats.errors import MocapFormatError
from mocapzip.formats.text import write_file_atomically

OVERLAID = 5  # up to this many clips share one chart; more are small multiples
MOST_PANELS = 36  # small multiples beyond this are too small to read: narrow --clip
MISSING = "needs matplotlib: pip install 'mocapzip[plot]'"


def _pyplot():
    """pyplot on the Agg backend (no display needed), or a one-line error naming the extra."""
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        raise MocapFormatError(f"plotting {MISSING}") from None
    return plt


def source_positions(clip: mocapzip.Clip, folder: str | os.PathLike) -> np.ndarray:
    """(frames, joints, 3) joint positions in cm of `clip`'s source file under `folder` (the folder
    the archive was compressed from), as `clip.positions()` gives the decoded ones."""
    path = Path(folder) / clip.path
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)  # a source cut short mid-frame: dropped, as compress did
        if clip.format == "bvh":
            positions = mocapzip.bvh_joint_positions(mocapzip.read_bvh(path), clip.units)  # as compressed
        else:
            positions = mocapzip.joint_positions(clip.skeleton, mocapzip.read_amc(path, clip.skeleton))
    if positions.shape[:2] != (clip.frames, len(clip.joint_names)):
        raise MocapFormatError(f"{positions.shape[0]} frames of {positions.shape[1]} joints, the archive's "
                               f"{clip.path} has {clip.frames} of {len(clip.joint_names)}: not its source", path)
    return positions


def joint_errors(clip: mocapzip.Clip, folder: str | os.PathLike) -> np.ndarray:
    """(frames, joints) distance in cm of each decoded joint from the source's."""
    return np.linalg.norm(clip.positions() - source_positions(clip, folder), axis=-1)


def _clips(archive: mocapzip.MocapArchive, pattern: str | None) -> list:
    clips = archive.glob(pattern) if pattern else list(archive)
    if not clips:
        raise MocapFormatError(f"no clip matches {pattern}", archive.path)
    return clips


def plot(archive_path, folder, output, pattern: str | None = None, kind: str = "time", force: bool = False) -> int:
    """Draw the errors of the archive's clips (those matching `pattern`) against their sources
    under `folder` into `output` (.png or .svg): `kind` "time", each frame's mean joint error (and
    its worst joint, faint) over time; "joints", each joint's mean error (bars) and 99th
    percentile (whiskers), one chart per skeleton; "vertex", each frame's worst vertex by ACL's
    metric over time (docs/acl.md). Returns the number of clips drawn."""
    from mocapzip.progress import progress

    output = Path(output)
    _refuse_existing(output, force)
    plt = _pyplot()
    with mocapzip.open(archive_path) as archive:
        clips = _clips(archive, pattern)
        if kind != "joints" and len(clips) > MOST_PANELS:
            raise MocapFormatError(f"{len(clips)} clips match; --kind {kind} draws at most {MOST_PANELS} "
                                   "(narrow --clip, or --kind joints)", archive.path)
        series = []
        for clip in progress(clips, desc="errors", unit="clip"):
            if kind == "vertex":
                shell = clip.shell_error(Path(folder) / clip.path)
                series.append((clip, shell.per_frame, None))
            else:
                errors = joint_errors(clip, folder)
                series.append((clip, errors.mean(axis=1), errors) if kind == "time" else (clip, None, errors))
        fig = _joints_figure(plt, series) if kind == "joints" else _time_figure(plt, series, kind)
    _save_figure(plt, fig, output)
    return len(clips)


def _time_figure(plt, series: list, kind: str):
    """Per-frame error over time: overlaid lines for a few clips, small multiples for more."""
    what = "worst vertex (ACL's metric), cm" if kind == "vertex" else "mean joint error, cm"
    if len(series) <= OVERLAID:
        fig, ax = plt.subplots(figsize=(8, 3.6))
        for clip, per_frame, errors in series:
            seconds = np.arange(clip.frames) / clip.fps
            (line,) = ax.plot(seconds, per_frame, lw=1.2, label=f"{clip.path} (mean {per_frame.mean():.2f} cm)")
            if errors is not None and len(series) == 1:  # over several clips' lines, a tangle
                ax.plot(seconds, errors.max(axis=1), lw=0.6, alpha=0.35, color=line.get_color())
        _time_axes(ax, what)
        ax.legend(fontsize=8, loc="upper right")
        note = "; faint: the frame's worst joint" if kind == "time" and len(series) == 1 else ""
        ax.set_title(f"error per frame against the source{note}", fontsize=10)
    else:
        cols = 3
        rows = math.ceil(len(series) / cols)
        fig, axes = plt.subplots(rows, cols, figsize=(11, 1.9 * rows + 0.6), sharey=True, squeeze=False)
        for ax, (clip, per_frame, errors) in zip(axes.flat, series):
            seconds = np.arange(clip.frames) / clip.fps
            if errors is not None:
                ax.plot(seconds, errors.max(axis=1), lw=0.5, alpha=0.35, color="C0")
            ax.plot(seconds, per_frame, lw=0.9, color="C0")
            ax.set_title(f"{clip.path}: {per_frame.mean():.2f} cm", fontsize=8)
            ax.tick_params(labelsize=7)
            ax.grid(True, alpha=0.3)
            ax.set_ylim(bottom=0)
        for ax in axes.flat[len(series):]:
            ax.set_visible(False)
        fig.supxlabel("seconds", fontsize=9)
        fig.supylabel(what, fontsize=9)
    fig.tight_layout()
    return fig


def _time_axes(ax, what: str) -> None:
    ax.set_xlabel("seconds")
    ax.set_ylabel(what)
    ax.set_ylim(bottom=0)
    ax.set_xlim(left=0)
    ax.grid(True, alpha=0.3)


def _joints_figure(plt, series: list):
    """Each joint's error over the frames of every clip, one horizontal bar chart per skeleton
    (clips whose joints have the same names share one)."""
    groups: dict[tuple, list] = {}
    for clip, _, errors in series:
        groups.setdefault(tuple(clip.joint_names), []).append(errors)
    heights = [0.17 * len(names) + 1.0 for names in groups]
    fig, axes = plt.subplots(1, len(groups), figsize=(4.6 * len(groups), max(heights)), squeeze=False)
    for ax, (names, members) in zip(axes.flat, groups.items()):
        errors = np.concatenate(members)
        mean, p99 = errors.mean(axis=0), np.percentile(errors, 99, axis=0)
        at = np.arange(len(names))
        ax.barh(at, mean, color="C0", xerr=[np.zeros_like(mean), p99 - mean], error_kw={"lw": 0.7, "alpha": 0.6})
        ax.set_yticks(at, names, fontsize=7)
        ax.invert_yaxis()  # the root at the top, as the files list joints
        ax.set_xlabel("joint error, cm: mean (bar), 99th percentile (whisker)", fontsize=8)
        ax.set_title(f"error per joint against the source\n{len(members)} clip{'s' if len(members) > 1 else ''}, "
                     f"{len(errors):,} frames", fontsize=9)
        ax.grid(True, axis="x", alpha=0.3)
    fig.tight_layout()
    return fig


def _save_figure(plt, fig, output: Path) -> None:
    buffer = io.BytesIO()
    try:
        fig.savefig(buffer, format=output.suffix.lower()[1:], dpi=100)
    finally:
        plt.close(fig)
    write_file_atomically(output, buffer.getvalue())


def _refuse_existing(output: Path, force: bool) -> None:
    if os.path.lexists(output) and not force:
        raise FileExistsError(None, "already exists", os.fspath(output))


# --------------------------------------------------------------------------- view


def ffmpeg_available() -> bool:
    from matplotlib.animation import FFMpegWriter

    return FFMpegWriter.isAvailable()


def view(archive_path, name: str, output, folder=None, fps: float = 30.0, frames: slice = slice(None),
         max_frames: int = 300, overlay: bool = False, force: bool = False) -> tuple[int, int]:
    """Animate the clip `name` of the archive (decoded) beside its source under `folder` (or over
    it, in two colours, with `overlay`; alone without `folder`) into `output`: .gif, .mp4 (needs
    ffmpeg) or .html (one self-contained page). Frames `frames` of the clip, at `fps` (subsampled,
    never faster than the clip), at most `max_frames` of them. Returns (frames drawn, frames in the range)."""
    output = Path(output)
    _refuse_existing(output, force)
    plt = _pyplot()
    with mocapzip.open(archive_path) as archive:
        try:
            whole = archive[name]
        except KeyError as exc:
            raise MocapFormatError(exc.args[0]) from None
        clip = whole[frames]
        if clip.frames == 0:
            raise MocapFormatError(f"{whole.path} has {whole.frames} frames: none in {frames.start}:{frames.stop}",
                                   archive.path)
        decoded = clip.positions()
        source = None
        if folder is not None:
            source = source_positions(whole, folder)[frames]
        parents = clip.parents
    step = max(1, round(clip.fps / fps))
    picked = np.arange(0, clip.frames, step)[:max_frames]
    seconds = (frames.indices(whole.frames)[0] + picked) / clip.fps
    fig, update = _stick_figures(plt, clip.path, decoded, source, parents, picked, seconds, overlay)
    try:
        data = _animation_bytes(fig, update, len(picked), clip.fps / step, output.suffix.lower(), clip.path)
    finally:
        plt.close(fig)
    write_file_atomically(output, data)
    return len(picked), clip.frames


def _stick_figures(plt, name: str, decoded: np.ndarray, source: np.ndarray | None, parents: np.ndarray,
                   picked: np.ndarray, seconds: np.ndarray, overlay: bool):
    """The figure and its per-frame update: one 3D panel per skeleton (or one with both), the camera
    following the root across the floor. Files are Y-up; matplotlib's 3D axes are Z-up."""
    def lifted(p):  # (x, y, z) Y-up, right-handed -> (x, -z, y) Z-up, right-handed
        return np.stack([p[..., 0], -p[..., 2], p[..., 1]], axis=-1)

    decoded = lifted(decoded[picked])
    shown = {"decoded": decoded} if source is None else {"source": lifted(source[picked]), "decoded": decoded}
    anchor = next(iter(shown.values()))[:, 0]  # the root the camera follows
    reach = max(float(np.abs(p[..., :2] - anchor[:, None, :2]).max()) for p in shown.values()) * 1.1 + 1
    low = min(float(p[..., 2].min()) for p in shown.values())
    high = max(float(p[..., 2].max()) for p in shown.values())
    panels = 1 if overlay or source is None else 2
    fig = plt.figure(figsize=(2.8 * panels + 0.4, 3.2), dpi=72)
    axes = [fig.add_subplot(1, panels, i + 1, projection="3d") for i in range(panels)]
    bones = [j for j in range(len(parents)) if parents[j] >= 0]
    colours = {"source": "0.6", "decoded": "tab:red"}
    floor = _floor_lines(anchor, reach, low)
    drawn = []  # (axes, positions, lines)
    for i, (label, positions) in enumerate(shown.items()):
        ax = axes[0 if panels == 1 else i]
        width = 3.0 if panels == 1 and label == "source" else 1.5  # overlaid, the source shows round the decoded
        lines = [ax.plot([], [], [], color=colours[label], lw=width)[0] for _ in bones]
        drawn.append((ax, positions, lines))
        lines[0].set_label(label)
    for ax in axes:
        for x, y in floor:
            ax.plot(x, y, [low, low], color="0.85", lw=0.8)
        ax.set_box_aspect((2 * reach, 2 * reach, high - low))
        ax.set_zlim(low, high)
        ax.view_init(elev=12, azim=-60)
        ax.set_axis_off()
    if panels == 1:
        axes[0].legend(loc="upper left", fontsize=7, frameon=False)
    else:
        for ax, label in zip(axes, shown):
            ax.set_title(label, fontsize=8, color=colours[label])
    errors = None if source is None else np.linalg.norm(shown["decoded"] - shown["source"], axis=-1).mean(axis=1)
    title = fig.suptitle("", fontsize=8)
    fig.subplots_adjust(left=0, right=1, bottom=0, top=0.86, wspace=0)

    def update(k: int):
        centre = anchor[k]
        for ax, positions, lines in drawn:
            ax.set_xlim(centre[0] - reach, centre[0] + reach)
            ax.set_ylim(centre[1] - reach, centre[1] + reach)
            p = positions[k]
            for line, j in zip(lines, bones):
                segment = p[[parents[j], j]]
                line.set_data_3d(segment[:, 0], segment[:, 1], segment[:, 2])
        error = "" if errors is None else f", mean joint error {errors[k]:.2f} cm"
        title.set_text(f"{name}\n{seconds[k]:.2f} s{error}")
        return []

    return fig, update


def _floor_lines(anchor: np.ndarray, reach: float, height: float, spacing: float = 50.0) -> list:
    """A grid on the floor every `spacing` cm under the whole path of the root: it stays put
    while the camera follows the root, so the figure is seen to travel."""
    low = np.floor((anchor[:, :2].min(axis=0) - reach) / spacing) * spacing
    high = np.ceil((anchor[:, :2].max(axis=0) + reach) / spacing) * spacing
    lines = [([x, x], [low[1], high[1]]) for x in np.arange(low[0], high[0] + 1, spacing)]
    return lines + [([low[0], high[0]], [y, y]) for y in np.arange(low[1], high[1] + 1, spacing)]


def _animation_bytes(fig, update, frames: int, fps: float, suffix: str, name: str) -> bytes:
    from matplotlib.animation import FFMpegWriter, FuncAnimation, PillowWriter

    animation = FuncAnimation(fig, update, frames=frames, interval=1000 / fps, repeat=True)
    if suffix == ".html":
        return _self_contained(animation.to_jshtml(fps=fps, default_mode="loop"), name).encode("utf-8")
    writer = PillowWriter(fps=fps) if suffix == ".gif" else FFMpegWriter(fps=fps)
    with tempfile.TemporaryDirectory() as scratch:  # the writers want a file name; the output is written atomically
        path = Path(scratch) / f"view{suffix}"
        animation.save(path, writer=writer)
        return path.read_bytes()


# matplotlib's player draws its buttons with Font Awesome, a stylesheet it links from a CDN: text instead
BUTTONS = {"fa-minus": "&minus;", "fa-fast-backward": "&#x23EE;", "fa-step-backward": "|&#x25C1;",
           "fa-play fa-flip-horizontal": "&#x25C0;", "fa-pause": "&#x275A;&#x275A;", "fa-play": "&#x25B6;",
           "fa-step-forward": "&#x25B7;|", "fa-fast-forward": "&#x23ED;", "fa-plus": "+"}


def _self_contained(fragment: str, name: str) -> str:
    """matplotlib's `to_jshtml` player as a page that loads nothing from elsewhere."""
    fragment = re.sub(r"<link\b[^>]*>", "", fragment)
    fragment = re.sub(r'<i class="fa ([^"]*)"></i>', lambda m: BUTTONS.get(m[1], m[1].removeprefix("fa-")), fragment)
    title = name.replace("&", "&amp;").replace("<", "&lt;")
    return (f'<!DOCTYPE html>\n<html><head><meta charset="utf-8"><title>{title}</title></head>\n<body>\n'
            f"{fragment}\n</body></html>\n")
