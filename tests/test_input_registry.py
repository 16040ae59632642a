"""An input format is one registration (`mocapzip.inputs.registry`, issue 41): a toy format declared
here in a few lines (a suffix, its skeleton, a reader and a writer) goes through `mcz compress`,
`decompress` and `test`, lossless and lossy, with nothing else in the package knowing of it.

The toy format: a clip is a text file of its channels (`.chan`), one frame per line, the values
separated by commas, on one fixed skeleton (CMU subject 09's ASF), its bones in the order of CMU's
AMC files. Its clips are the real ones of cmu/09, written as .chan files.
"""

from __future__ import annotations

import json

import numpy as np
import pytest
from click.testing import CliRunner

import mocapzip
from mocapzip.archive.reader import Archive
from mocapzip.cli.main import main
from mocapzip.formats.amc import Motion, read_amc
from mocapzip.formats.asf import read_asf
from mocapzip.inputs.registry import AMC, InputFormat, SourceMotion, register, unregister
from mocapzip.motion.kinematics import forward
from mocapzip.motion.skeleton import ChannelLayout, SkeletonModel


def chan_text(values: np.ndarray) -> bytes:
    """A .chan file of `values` (frames, channels)."""
    return "".join(",".join("%.6g" % v for v in row) + "\n" for row in values).encode()


@pytest.fixture
def chan_folder(request, shared_data, tmp_path):
    """A folder of cmu/09's clips as .chan files, the format registered while the test runs (with the
    API hooks a test passes as its parameter, else none)."""
    subject = shared_data / "cmu" / "09"
    clips = [read_amc(path) for path in sorted(subject.glob("*.amc"))]
    bones, counts = clips[0].bones, clips[0].counts
    assert all((clip.bones, clip.counts) == (bones, counts) for clip in clips)
    asf = (subject / "09.asf").read_bytes()

    def read(source, skeleton, lossless):
        values = np.loadtxt(source.motion, delimiter=",", ndmin=2)
        motion = Motion(bones, counts, values, np.arange(1, len(values) + 1), path=str(source.motion))
        return SourceMotion(skeleton.skeleton, skeleton.model, motion, None, "deg", values.shape[1])

    def write(archive, index):  # the file in blocks: here one
        return [chan_text(archive.decode(index).values)]

    # the whole format: its name and suffix, its skeleton's text (an ASF, read as an AMC's), reader, writer
    register(InputFormat("chan", (".chan",), lambda path: asf, AMC.read_skeleton, read, write,
                         api=getattr(request, "param", None)))
    folder = tmp_path / "chan"
    folder.mkdir()
    for clip in clips:
        (folder / clip.path.replace(".amc", ".chan").rpartition("/")[2]).write_bytes(chan_text(clip.values))
    yield folder
    unregister("chan")


def mcz(*args: str) -> str:
    result = CliRunner().invoke(main, list(args))
    assert result.exit_code == 0, result.output
    return result.output


def test_a_registered_format_comes_back_byte_for_byte_lossless(chan_folder, tmp_path):
    archive, out = tmp_path / "chan.mcz", tmp_path / "out"
    mcz("compress", str(chan_folder), "--lossless", "-o", str(archive), "-q")
    mcz("test", str(archive), "-q")
    mcz("decompress", str(archive), "-o", str(out), "-q")
    sources = sorted(chan_folder.iterdir())
    assert sorted(p.name for p in out.iterdir()) == [p.name for p in sources]  # no skeleton file: the format has it
    for source in sources:
        assert (out / source.name).read_bytes() == source.read_bytes()
    with Archive(archive) as opened:  # the clips' format, by their skeleton's entry in meta
        assert opened.meta["skeletons"] == [{"name": sources[0].name, "format": "chan"}]
    # info lists the skeletons of every format but ASF's, as the format describes them
    assert json.loads(mcz("info", "--json", str(archive)))["chan_skeletons"] == [{"name": sources[0].name}]
    assert "\nskeletons: 1 skeleton\n" in mcz("info", str(archive))
    with mocapzip.open(archive) as opened:  # the API reads a format only as the format says (`InputFormat.api`)
        with pytest.raises(AttributeError, match="is a CHAN clip, which the API does not read"):
            opened[0].positions()


# read as an AMC clip (its `motion`), without an ASF file of its own, saved as a .chan file
CHAN_API = AMC.api._replace(also_has=(), own_files=lambda clip: [chan_text(clip.channels)])


@pytest.mark.parametrize("chan_folder", [CHAN_API], indirect=True)
def test_the_api_reads_a_format_as_its_hooks_say(chan_folder, shared_data, tmp_path):
    mcz("compress", str(chan_folder), "--lossless", "-o", str(tmp_path / "chan.mcz"), "-q")
    source = read_amc(shared_data / "cmu" / "09" / "09_01.amc")
    model = SkeletonModel.from_asf(read_asf(shared_data / "cmu" / "09" / "09.asf"))
    with mocapzip.open(tmp_path / "chan.mcz") as opened:
        clip = opened["09_01.chan"]
        assert clip.format == "chan" and clip.channel_labels[:4] == ("root.tx", "root.ty", "root.tz", "root.rx")
        assert np.allclose(clip.channels, source.values, rtol=0, atol=1e-6)  # as %.6g wrote them
        assert np.allclose(clip.positions(), forward(model, source.values, source).positions, rtol=0, atol=1e-4)
        assert clip.save(tmp_path / "x.chan") == [str(tmp_path / "x.chan")]
        assert (tmp_path / "x.chan").read_bytes() == chan_text(clip.channels)
        with pytest.raises(ValueError, match="save writes .chan files, not .amc"):  # it declares no conversion
            clip.save(tmp_path / "x.amc")
        assert clip.motion.bones == source.bones
        with pytest.raises(AttributeError, match="is a CHAN clip: it has no asf_text"):
            clip.asf_text


def test_a_row_field_comes_with_its_schema():
    with pytest.raises(ValueError, match="'toy': a row field comes with its schema"):
        InputFormat("toy", (".toy",), AMC.skeleton_text, AMC.read_skeleton, AMC.read, AMC.write, row_field="toy")


def test_a_registered_format_decodes_within_the_error(chan_folder, shared_data, tmp_path):
    archive, out = tmp_path / "chan.mcz", tmp_path / "out"
    mcz("compress", str(chan_folder), "-e", "1", "-o", str(archive), "-q")
    mcz("decompress", str(archive), "-o", str(out), "-q")
    stored = {row["path"]: row["error_cm"] for row in json.loads(mcz("info", "--json", str(archive)))["clips"]}
    assert sorted(stored) == sorted(p.name for p in chan_folder.iterdir())
    model = SkeletonModel.from_asf(read_asf(shared_data / "cmu" / "09" / "09.asf"))
    layout = read_amc(shared_data / "cmu" / "09" / "09_01.amc")
    layout = ChannelLayout(tuple(layout.bones), tuple(layout.counts), "deg")
    for name, error_cm in stored.items():
        source, decoded = (np.loadtxt(folder / name, delimiter=",", ndmin=2) for folder in (chan_folder, out))
        assert decoded.shape == source.shape
        distances = np.linalg.norm(forward(model, decoded, layout).positions - forward(model, source, layout).positions,
                                   axis=-1)
        assert 0 < distances.mean() <= error_cm + 1e-6 <= 1 + 1e-6  # as the archive says, within -e


def test_convert_refuses_a_format_it_has_no_conversion_for(chan_folder, tmp_path):
    result = CliRunner().invoke(main, ["convert", str(chan_folder), "-o", str(tmp_path / "out")])
    assert result.exit_code == 1
    assert "mcz convert turns AMC clips into BVH and BVH into ASF/AMC, not CHAN clips" in result.output
    assert not (tmp_path / "out").exists()
