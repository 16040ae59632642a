"""Inputs that could hang `mcz` or exhaust memory (issue 13, items 1 and 14): FIFOs, a link to
/dev/zero, files beyond the size limits, a skeleton of 20,000 bones.

Each runs `mcz` in a child process with a timeout and an address-space limit, so a regression
fails the test instead of hanging the suite or the machine. The timeouts only catch hangs:
every case takes a few seconds at most.
"""

from __future__ import annotations

import json
import os
import re
import subprocess

import pytest

import hostile_inputs
from limited import run_mcz

def run_limited(folder, *args) -> subprocess.CompletedProcess:
    """`mcz ARGS` run in `folder`, under the limits of `limited.run_mcz`."""
    return run_mcz(*args, cwd=folder)


@pytest.fixture(scope="module")
def specials(tmp_path_factory, shared_data):
    root = tmp_path_factory.mktemp("specials")
    return root, hostile_inputs.build_specials(root, shared_data)


def expected(case) -> str:
    where = re.escape(case.file) + (f":{case.line}" if case.line is not None else "")
    return rf"mcz: error: (.*/)?{where}: .*{re.escape(case.problem)}.*"


@pytest.mark.slow
def test_special_and_oversized_inputs_are_refused_in_one_line(specials, tmp_path):
    root, cases = specials
    failures = {}
    for case in cases:
        args = case.args + (["-o", tmp_path / "db.mcz", "-q"] if case.args[0] == "compress" else [])
        result = run_limited(root / case.name, *args)
        lines = result.stderr.splitlines()
        if result.returncode != 1 or len(lines) != 1 or not re.fullmatch(expected(case), lines[0]) or result.stdout:
            failures[f"{case.name}: mcz {' '.join(case.args)}"] = (result.returncode, result.stderr[-2000:])
    assert failures == {}
    assert os.listdir(tmp_path) == []


def test_skip_bad_lists_the_special_file_and_keeps_the_good_clip(specials, tmp_path):
    root, cases = specials
    for case in (c for c in cases if c.skip):
        result = run_limited(root / case.name, *case.args, "-o", tmp_path / f"{case.name}.mcz", "--skip-bad", "--json")
        assert result.returncode == 0, (case.name, result.stderr)
        summary = json.loads(result.stdout)
        assert summary["clips"] == 1
        (skipped,) = summary["skipped"]
        assert skipped["path"] == case.skip and re.fullmatch(expected(case), "mcz: error: " + skipped["error"])
        assert result.stderr.splitlines() == [f"mcz: warning: skipped {case.skip}: {skipped['error']}"]


def test_a_chain_up_to_the_bone_limit_is_read(specials):
    """The hierarchy checks are linear: a skeleton of 1,024 bones, most in one chain, is read."""
    root, _ = specials
    result = run_limited(root / "chain_up_to_the_bone_limit", "inspect", "--json", ".")
    assert result.returncode == 0, result.stderr
    assert json.loads(result.stdout)["total"]["frames"] == 148


@pytest.mark.parametrize("command", [["inspect"], ["compress", "--lossless", "-o", "db.mcz"], ["convert", "-o", "out"]])
def test_a_link_to_a_device_named_on_the_command_line_is_refused_as_a_device(tmp_path, command):
    """A link to /dev/zero given as a file was refused as "symbolic link loop or dangling symbolic
    link": the link test came before the test of what it points to (found in a folder, it was
    refused as a device already)."""
    (tmp_path / "zero.bvh").symlink_to("/dev/zero")
    os.mkfifo(tmp_path / "pipe.amc")
    os.symlink("pipe.amc", tmp_path / "pipe_link.amc")
    for name, kind in (("zero.bvh", "a character device (/dev/zero)"), ("pipe_link.amc", "a named pipe (FIFO)")):
        result = run_limited(tmp_path, command[0], name, *command[1:])
        lines = result.stderr.splitlines()
        assert result.returncode == 1 and len(lines) == 1, result.stderr
        assert lines[0].startswith(f"mcz: error: {name}: not a regular file: {kind}"), lines[0]  # and where it links
    assert sorted(os.listdir(tmp_path)) == ["pipe.amc", "pipe_link.amc", "zero.bvh"]


def sparse(path, head: bytes, size: int) -> None:
    """`head`, then zeros up to `size` bytes that take no disk space."""
    path.write_bytes(head)
    os.truncate(path, size)


@pytest.mark.parametrize("name, args, file, limit, what", [
    ("bvh", ["inspect", "big.bvh"], "big.bvh", "213,925,888", "a BVH file"),
    ("bvh", ["compress", "big.bvh", "--lossless", "-o", "db.mcz"], "big.bvh", "213,925,888", "a BVH file"),
    ("bvh", ["convert", "big.bvh", "-o", "out"], "big.bvh", "213,925,888", "a BVH file"),
    ("asf", ["inspect", "09_01.amc"], "09.asf", "16,777,216", "an ASF file"),
    ("asf", ["convert", "09_01.amc", "-o", "out"], "09.asf", "16,777,216", "an ASF file"),
    ("asf_option", ["inspect", "09_01.amc", "--asf", "big.asf"], "big.asf", "16,777,216", "an ASF file"),
    ("class_table", ["compress", "09_01.amc", "-c", "big.csv", "-o", "db.mcz"], "big.csv", "268,435,456",
     "a class table"),
])
def test_a_file_larger_than_its_format_allows_is_refused_unread(shared_data, tmp_path, name, args, file, limit, what):
    """A sparse file takes no disk space but claims gigabytes: BVH, ASF and class-table files were
    read whole ("out of memory", naming no file, under the hostile suites' limit), as AMC files
    are not. Each is refused by its size before a byte is read."""
    amc = (shared_data / hostile_inputs.SUBJECT / hostile_inputs.AMC_NAME).read_bytes()
    asf = (shared_data / hostile_inputs.SUBJECT / hostile_inputs.ASF_NAME).read_bytes()
    (tmp_path / "09_01.amc").write_bytes(amc[:20_000])
    sparse(tmp_path / "09.asf", asf, 3 << 30 if name == "asf" else len(asf))
    if name == "asf_option":
        sparse(tmp_path / "big.asf", asf, 3 << 30)
    sparse(tmp_path / "big.csv", b"09_01.amc,a\n", 3 << 30)
    sparse(tmp_path / "big.bvh", (shared_data / "bvh-bandai" / "dataset-1_bow_active_001.bvh").read_bytes(), 3 << 30)
    before = sorted(os.listdir(tmp_path))
    result = run_mcz(*args, cwd=tmp_path, memory=1 << 30)
    assert result.returncode == 1 and result.stderr == (
        f"mcz: error: {file}: file of 3,221,225,472 bytes is larger than the {limit} bytes {what} may have\n"), (
        result.stderr)
    assert sorted(os.listdir(tmp_path)) == before
