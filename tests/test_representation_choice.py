"""`representation="auto"`, compress's default: `channels` where the error (or the vertex bound)
times the frame rate is below its threshold, `aligned` elsewhere (the smaller of the two there,
docs/fidelity.md), and archives name the one used."""

from __future__ import annotations

import json

import numpy as np
import pytest
from click.testing import CliRunner

import mocapzip
from mocapzip.archive.edit import append
from mocapzip.archive.settings import Settings, SettingsError, checked, chosen_representation
from mocapzip.cli.main import main
from mocapzip.defaults import CHANNELS_BELOW_CM_HZ, CHANNELS_BELOW_VERTEX_CM_HZ, DEFAULT_FPS
from mocapzip.formats.amc import read_amc
from mocapzip.formats.asf import read_asf

EDGE_CM = CHANNELS_BELOW_CM_HZ / DEFAULT_FPS  # the threshold at the default rate (120 fps)
TIGHT_CM = EDGE_CM / 2


@pytest.mark.parametrize(("changes", "used"), [
    ({"error_cm": TIGHT_CM}, "channels"), ({"error_cm": EDGE_CM}, "aligned"), ({}, "aligned"),
    ({"error_cm": 4 * EDGE_CM, "fps": DEFAULT_FPS / 5}, "channels"),  # at 24 fps the crossover is 5x looser
    ({"error_cm": EDGE_CM, "fps": 2 * DEFAULT_FPS}, "aligned"),
    ({"error_cm": 3 * EDGE_CM, "vertex_error_cm": CHANNELS_BELOW_VERTEX_CM_HZ / DEFAULT_FPS / 2}, "channels"),
    ({"error_cm": 3 * EDGE_CM, "vertex_error_cm": CHANNELS_BELOW_VERTEX_CM_HZ / DEFAULT_FPS}, "aligned"),
    ({"error_cm": TIGHT_CM, "representation": "aligned"}, "aligned"), ({"representation": "channels"}, "channels")])
def test_auto_picks_by_the_error_and_rate_and_a_named_representation_stays(changes, used):
    settings = Settings(**changes)
    assert chosen_representation(settings) == used and checked(settings).representation == used


def test_an_unknown_name_is_refused_before_any_clip_is_read():
    with pytest.raises(SettingsError, match="unknown representation id 'quaternions'"):
        checked(Settings(representation="quaternions"))


def test_auto_stores_channels_below_the_threshold_decodes_within_e_and_append_keeps_it(shared_data, tmp_path):
    folder = shared_data / "cmu" / "09"
    asf, clip, other = folder / "09.asf", folder / "09_03.amc", folder / "09_08.amc"
    out = tmp_path / "tight.mcz"
    summary = mocapzip.compress([asf, clip], out, error=TIGHT_CM, max_error=None, jobs=1, progress=False)
    source = mocapzip.joint_positions(read_asf(asf), read_amc(clip))
    with mocapzip.open(out) as archive:
        assert archive.settings.representation == "channels"
        decoded = archive[0].positions()
    mean = np.linalg.norm(decoded - source, axis=-1).mean()
    assert mean <= TIGHT_CM and summary["largest_mean_error_cm"] <= TIGHT_CM
    append(out, [asf, other], force=True)
    with mocapzip.open(out) as archive:
        assert archive.settings.representation == "channels" and len(archive) == 2


def test_the_command_line_defaults_to_auto_and_info_names_the_one_used(shared_data, tmp_path):
    clip = shared_data / "cmu" / "09" / "09_03.amc"
    runner = CliRunner()
    assert "auto" in runner.invoke(main, ["compress", "--help"]).output
    result = runner.invoke(main, ["compress", str(clip.with_name("09.asf")), str(clip), "-o", str(tmp_path / "a.mcz"),
                                  "-q", "-j", "1"])
    assert result.exit_code == 0, result.output
    info = runner.invoke(main, ["info", str(tmp_path / "a.mcz"), "--json"])
    assert json.loads(info.output)["settings"]["representation"] == "aligned"
    refused = runner.invoke(main, ["compress", str(clip), "-o", str(tmp_path / "b.mcz"), "-r", "quaternions"])
    assert refused.exit_code == 2 and "'quaternions' is not one of 'auto'" in refused.output
