"""Format 7's zstd dictionaries and format 10's skeleton means: frozen, checked, made as their script
says, and worth their bytes."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import pytest

from mocapzip.archive import dictionaries
from mocapzip.archive.dictionaries import dictionary
from mocapzip.codec.entropy.zstd import decode_bytes, encode_bytes, pack_blobs, unpack_blobs

SCRIPT = Path(__file__).parent / "make_format_dictionaries.py"


def load_script():
    spec = importlib.util.spec_from_file_location("make_format_dictionaries", SCRIPT)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_the_asf_templates_are_what_their_script_makes_from_the_shared_data(shared_data):
    assert load_script().asf_templates() == dictionary("asf.txt")


def test_the_family_means_are_what_their_script_makes_from_the_shared_data(shared_data):
    assert load_script().asf_means() == dictionary("asf_means.txt")


def test_every_shared_skeleton_round_trips_and_costs_far_less_with_the_templates(shared_data):
    paths = sorted(shared_data.glob("cmu/*/*.asf")) + sorted(shared_data.glob("hdm05/*/*.asf"))
    assert len(paths) == 16
    for path in paths:
        text = path.read_bytes()
        coded = encode_bytes(pack_blobs([text]), dictionary("asf.txt"))
        assert unpack_blobs(decode_bytes(coded, dictionary=dictionary("asf.txt"))) == [text]
        # measured 560-640 B, against about 1,460 B without the dictionary
        assert len(coded) < 700 < 0.5 * len(encode_bytes(text)), (path, len(coded))


def test_a_frame_needs_its_dictionary():
    text = dictionary("meta.json")[:1000]
    coded = encode_bytes(text, dictionary("meta.json"))
    assert len(coded) < 40
    with pytest.raises(ValueError):
        decode_bytes(coded)


def test_a_damaged_dictionary_stops_with_a_clear_error(monkeypatch, tmp_path):
    (tmp_path / "meta.json").write_bytes(dictionary("meta.json")[:-1] + b" ")
    monkeypatch.setattr(dictionaries.resources, "files", lambda package: tmp_path)
    dictionary.cache_clear()
    try:
        with pytest.raises(RuntimeError, match="dictionary meta.json is not the one the format defines"):
            dictionary("meta.json")
    finally:
        monkeypatch.undo()
        dictionary.cache_clear()
