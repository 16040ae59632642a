"""`mcz compress`: clips on disk -> the streams of one .mcz archive (the newest format, `FORMAT_VERSION`),
as a recipe of passes (`archive/passes/`), each taking and giving frozen records.

Streams (see docs/format.md, "Streams written by the codec"):
  meta        zstd JSON (dictionary meta.json): settings, skeleton and class tables, one row per clip
  skeletons   the ASF files and BVH hierarchies, byte for byte: the text between numbers by zstd, the numbers
              predicted from an earlier skeleton or a family's means and range coded (archive/skeletons.py)
  class/NNNN  a class's quantised PCA mean and basis (lossy mode)
  priors      zstd bytes: where the clip streams' models start (coefficient coder "primed")
  clip/NNNNN  a clip's coefficient payload (lossy) or lossless channel code
  clip/NNNNN/SSS  segment SSS of a take cut by --segment (its row in meta lists the segments)
  extra_root/NNNNN  a lossy BVH clip's extra root's channels, lossless channel code (format 8 on)
  patch/NNNNN  a lossy clip's frame patches (--max-error, --contact-error; format 5 on)
  plant/NNNNN  the stances a lossy clip's foot lock holds (--plant-feet; format 9 on)
  tensor/NNNN  a class's tensor model (--model tensor; format 11 on)
  warp/NNNNN   a clip's warping path onto its class's tensor model (format 11 on)
"""

from __future__ import annotations

import time

from mocapzip import __version__
from mocapzip.archive.passes.check import check
from mocapzip.archive.passes.class_coding import code_classes
from mocapzip.archive.passes.classes import classes_of
from mocapzip.archive.passes.entropy_pass import entropy_pass
from mocapzip.archive.passes.first_pass import first_pass, leave_out
from mocapzip.archive.passes.write import summary, write
from mocapzip.archive.settings import Settings
from mocapzip.defaults import DEFAULT_CACHE_MB
from mocapzip.formats.mcz import ArchiveWriter
from mocapzip.parallel import one_blas_thread
from mocapzip.ratecontrol.max_error import TargetError


@one_blas_thread
def compress(inputs, output, settings: Settings, asf=None, force: bool = False, jobs: int = 1,
             skip_bad: bool = False, cache_bytes: int | None = DEFAULT_CACHE_MB << 20, units: str | None = None) -> dict:
    """Compress every clip under `inputs` into `output`; return the summary (also stored in meta).
    `units`: of BVH files' lengths (a `UNITS_CM` name), where they cannot be inferred.

    With `skip_bad`, clips that cannot be read, or that no coding brings within the target or
    bounds (`TargetError`), are left out and listed in the summary's `skipped` (and the archive's
    meta) instead of stopping the run. A clip refused while its class is coded is left out of
    what the first pass read, and the classes are made and coded again without it, so that
    nothing of it stays in the archive (`first_pass.leave_out`).

    Clips stream through, so a database larger than memory compresses (docs/architecture.md):
    the first pass reads each clip to check it, note its row and code it (lossless) or add its
    poses to its class's covariance; then each class is coded, its clips read again unless
    they were kept in memory, which they are while they fit in `cache_bytes` (None: no limit).
    `--classes auto` and `--segment` analyse the poses of all clips together: they keep every
    clip in memory.
    """
    started = time.perf_counter()
    job = check(inputs, output, settings, asf, force, skip_bad, units)
    plan, target = job.settings.class_plan(), job.settings.coding_target()  # each pass takes the parts it reads
    reader = job.clip_reader(cache_bytes)
    with ArchiveWriter(job.output, tool_version=__version__, overwrite=force) as archive:
        clips = first_pass(job, reader, job.settings.clip_reading(), plan, archive, jobs)
        while True:
            classes = classes_of(clips, reader, plan, target, jobs)
            try:
                coded = code_classes(clips, classes, reader, plan, target, jobs)
                break
            except TargetError as refused:
                clips = leave_out(clips, refused, job, reader)
        stored = entropy_pass(coded, job.settings.chain(), jobs)
        written = write(job, clips, classes, coded, stored, archive)
    return summary(job, clips, written, time.perf_counter() - started)
