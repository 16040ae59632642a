"""An independent decoder for .mcz archives, written from docs/format.md alone.

It shares no code with mocapzip: tests/test_reference_decoder.py decodes archives with both and
compares, so a reader of the spec can trust that the spec, not the package, defines the format.
The parts follow the spec's chapters: `container` (layout, index, checksums), `streams` (lossy
codec streams, byte level), `lossless` (lossless clip streams), `geometry` (decoding a lossy
clip from coefficients to AMC values), `bvh` (decoding a BVH clip, format 8 on) and `skeletons`
(the `skeletons` stream, format 10 on). Trusted test
input only: it raises ValueError on what it checks, but it is not hardened against crafted files
as mocapzip is.
"""

from . import bvh, geometry, lossless, streams
from .container import Container, read_meta, read_skeletons
from .skeletons import read_skeletons as skeleton_files


def bvh_hierarchies(meta, skeletons, version) -> dict:
    """{skeleton index: bvh.Hierarchy} for the `skeletons` entries of `format` "bvh" (format 8 on)."""
    hierarchies = {}
    for k, entry in enumerate(meta["skeletons"]):
        if set(entry) == {"name"}:
            continue
        if version < 8 or entry.get("format") != "bvh":
            raise ValueError(f"skeletons[{k}]: fields {sorted(entry)} (a BVH entry, format 8 on)")
        hierarchies[k] = bvh.Hierarchy(skeletons[k].encode("latin-1"), entry)
    for row in meta["clips"]:
        if ("bvh" in row) != (row["skeleton"] in hierarchies):
            raise ValueError(f"{row['path']}: rows of BVH clips, exactly, have `bvh`")
    return hierarchies


def decode_archive(path, bvh_clips: dict | None = None) -> dict:
    """{clip path: float64 values} for every clip of the archive at `path`: an AMC clip's (frames,
    channels) AMC values, a BVH clip's (frames, width) file values.

    If `bvh_clips` is a dict it receives, per BVH clip, {"text": the bytes of the file `decompress`
    writes, "model_values": a lossy clip's channel values v of its model (None when lossless)}.
    """
    with Container(path) as container:
        version = container.format_version
        meta = read_meta(container.read("meta"), version)
        if version >= 10:
            skeletons = [text.decode("latin-1") for text in skeleton_files(container.read("skeletons"), meta)]
        else:
            skeletons = read_skeletons(container.read("skeletons"), version)
        hierarchies = bvh_hierarchies(meta, skeletons, version)
        settings = meta["settings"]
        values = {}

        def bvh_clip(row, file_values, model_values=None):
            """A BVH clip's values, checked; its text and model values to `bvh_clips`."""
            bvh.check_values(row, file_values)
            if bvh_clips is not None:
                text = bvh.text(hierarchies[row["skeleton"]], row, file_values)
                bvh_clips[row["path"]] = {"text": text, "model_values": model_values}
            return file_values

        if settings.get("lossless", False):
            for index, row in enumerate(meta["clips"]):
                hierarchy = hierarchies.get(row["skeleton"])
                if hierarchy is not None:
                    bvh.check_row(row, hierarchy.layout(), lossless=True)
                decoded = lossless.lossless_channels(container.read(f"clip/{index:05d}"), row, version)
                values[row["path"]] = decoded if hierarchy is None else bvh_clip(row, decoded)
            return values

        coder = settings.get("coefficient_coder", "zstd")
        priors = streams.read_priors(container.read("priors")) if coder == "primed" else None
        root_track = settings["representation"] in geometry.ROOT_TRACK_REPRESENTATIONS
        bases, tensors = {}, {}

        def class_basis(class_index):
            if class_index not in bases:
                bases[class_index] = streams.class_basis(container.read(f"class/{class_index:04d}"), version)
            return bases[class_index]

        for index, row in enumerate(meta["clips"]):
            def coefficients(stream, class_index, rows, index=index):
                """A coded stream's class mean and basis and its dequantised coefficients."""
                mean, basis = class_basis(class_index)
                name = f"clip/{index:05d}" if stream is None else stream
                pose, root = streams.clip_coefficients(container.read(name), version, coder, rows,
                                                       basis.shape[1], root_track, priors)
                return mean, basis, pose, root

            hierarchy = hierarchies.get(row["skeleton"])
            if hierarchy is None:
                def skeleton(axes_from_positions, text=skeletons[row["skeleton"]]):
                    return geometry.Skeleton(text, axes_from_positions)
            else:  # "Decoding a BVH clip": the model in place of the ASF's
                model = bvh.Model(hierarchy)
                bvh.check_row(row, (model.bones, model.counts), lossless=False)
                skeleton = model.skeleton

            def prediction(row, index=index):
                """A tensor class's prediction of the clip (format 11 on)."""
                k = row["class"]
                if meta["classes"][k].get("model") != "tensor":
                    raise ValueError(f"{row['path']}: tensor_at, but class {k} is no tensor")
                if k not in tensors:
                    tensors[k] = streams.tensor_model(container.read(f"tensor/{k:04d}"))
                levels, width = meta["classes"][k]["levels"], class_basis(k)[0].shape[0]
                if [f.shape[0] for f in tensors[k][2][2:]] != [len(v) for v in levels] or \
                        tensors[k][2][1].shape[0] != width:
                    raise ValueError(f"tensor/{k:04d}: not its class's grid and pose width")
                return streams.tensor_prediction(tensors[k], row["tensor_at"], container.read(f"warp/{index:05d}"),
                                                 row["frames"])

            decoded = geometry.lossy_channels(settings, version, row, skeleton, coefficients, prediction)
            if "planted_stances" in row:
                if version < 9:
                    raise ValueError("planted_stances in a format before 9")
                sk = skeleton(False)
                stances = streams.planted_stances(container.read(f"plant/{index:05d}"), row,
                                                  len(geometry.foot_joints(sk)))
                geometry.hold_planted_feet(decoded, stances, row, sk)
            if "patched_frames" in row:
                if version < 5:
                    raise ValueError("patched_frames in a format before 5")
                geometry.add_patches(decoded, streams.frame_patches(container.read(f"patch/{index:05d}"), row),
                                     row, skeleton(False))
            if hierarchy is None:
                values[row["path"]] = decoded
                continue
            extra = None
            if row["bvh"].get("extra_root"):
                if model.extra_root is None:
                    raise ValueError(f"{row['path']}: bvh.extra_root, but the hierarchy has no extra root")
                channels = hierarchy.joints[model.extra_root].channels
                extra = lossless.lossless_channels(container.read(f"extra_root/{index:05d}"),
                                                   {"frames": row["frames"], "counts": [len(channels)]}, version)
            values[row["path"]] = bvh_clip(row, model.file_values(decoded, extra), decoded)
        return values
