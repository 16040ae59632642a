"""What the archive's priors (coefficient coder "primed", format 3) save on real clips.

    python benchmarks/coder_priors.py [DIR ...] [-e CM] [-j N]

Compresses the folders (default: every subject of ../shared/data/cmu) into one archive with
the default settings, then codes the same quantised coefficients again with models that start
at 1/2 (coder "context", format 2) and prints both sizes of the clip streams. Both codings
hold the same integers, so the difference is the coder's alone.
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

from mocapzip.archive import Archive, Settings, compress
from mocapzip.formats.mcz import ArchiveReader
from mocapzip.codec.clip_stream import CodedClip

DATA = Path(__file__).resolve().parents[2] / "shared" / "data" / "cmu"


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("inputs", nargs="*", type=Path, default=[DATA])
    parser.add_argument("-e", "--error", type=float, default=1.0)
    parser.add_argument("-j", "--jobs", type=int, default=2)
    args = parser.parse_args(argv)
    with tempfile.TemporaryDirectory() as work:
        path = Path(work) / "priors.mcz"
        summary = compress(args.inputs, path, Settings(error_cm=args.error), jobs=args.jobs)
        with Archive(path) as archive:
            sizes, coder, priors = archive.stream_sizes(), archive.settings.coefficient_coder, archive.priors
        clips = [name for name in sizes if name.startswith("clip/")]
        primed = sum(sizes[name] for name in clips) + sizes.get("priors", 0)
        with ArchiveReader(path) as reader:
            plain = sum(len(CodedClip.from_payload(reader.read(name), coder, priors=priors).payload("context"))
                        for name in clips)
    print(f"{summary['clips']} clips, {summary['frames']} frames, archive {summary['output_bytes']} bytes "
          f"({summary['bytes_per_frame']:.3f} B/frame), coder chosen: {coder}")
    print(f"clip streams: {primed} bytes with priors (priors stream {sizes.get('priors', 0)} bytes included), "
          f"{plain} without: {primed / plain:.3f}")


if __name__ == "__main__":
    main()
