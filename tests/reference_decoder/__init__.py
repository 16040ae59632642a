"""An independent decoder for .mcz archives, written from docs/format.md alone.

It shares no code with mocapzip: tests/test_reference_decoder.py decodes archives with both and
compares, so a reader of the spec can trust that the spec, not the package, defines the format.
The parts follow the spec's chapters: `container` (layout, index, checksums), `streams` (lossy
codec streams, byte level), `lossless` (lossless clip streams) and `geometry` (decoding a lossy
clip from coefficients to AMC values). Trusted test input only: it raises ValueError on what it
checks, but it is not hardened against crafted files as mocapzip is.
"""

from . import geometry, lossless, streams
from .container import Container, read_meta, read_skeletons


def decode_archive(path) -> dict:
    """{clip path: float64 (frames, channels) AMC values} for every clip of the archive at `path`."""
    with Container(path) as container:
        version = container.format_version
        meta = read_meta(container.read("meta"), version)
        skeletons = read_skeletons(container.read("skeletons"), version)
        settings = meta["settings"]
        if settings.get("lossless", False):
            return {row["path"]: lossless.lossless_channels(container.read(f"clip/{index:05d}"), row, version)
                    for index, row in enumerate(meta["clips"])}

        coder = settings.get("coefficient_coder", "zstd")
        priors = streams.read_priors(container.read("priors")) if coder == "primed" else None
        root_track = settings["representation"] in geometry.ROOT_TRACK_REPRESENTATIONS
        bases = {}

        def class_basis(class_index):
            if class_index not in bases:
                bases[class_index] = streams.class_basis(container.read(f"class/{class_index:04d}"), version)
            return bases[class_index]

        values = {}
        for index, row in enumerate(meta["clips"]):
            def coefficients(stream, class_index, rows, index=index):
                """A coded stream's class mean and basis and its dequantised coefficients."""
                mean, basis = class_basis(class_index)
                name = f"clip/{index:05d}" if stream is None else stream
                pose, root = streams.clip_coefficients(container.read(name), version, coder, rows,
                                                       basis.shape[1], root_track, priors)
                return mean, basis, pose, root

            decoded = geometry.lossy_channels(settings, version, row, skeletons[row["skeleton"]], coefficients)
            if "patched_frames" in row:
                if version < 5:
                    raise ValueError("patched_frames in a format before 5")
                geometry.add_patches(decoded, streams.frame_patches(container.read(f"patch/{index:05d}"), row),
                                     row, skeletons[row["skeleton"]])
            values[row["path"]] = decoded
        return values
