"""The passes of compress take the parts of `Settings` they read, not the whole record: only the
check (which checks it) and the write (which stores it whole in meta) name it. Every setting
reaches some part, so a pass cannot miss one that the archive stores."""

import ast
from dataclasses import fields, replace
from pathlib import Path

import pytest

from mocapzip.archive.settings import Settings

PASSES = Path(__file__).resolve().parent.parent / "mocapzip" / "archive" / "passes"
WHOLE_RECORD = {"check.py", "write.py"}  # the check checks every field; the write stores them all


def _imports_settings(path: Path) -> bool:
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.ImportFrom) and node.module == "mocapzip.archive.settings":
            if any(alias.name == "Settings" for alias in node.names):
                return True
    return False


def test_only_check_and_write_import_settings():
    importing = {path.name for path in PASSES.glob("*.py") if _imports_settings(path)}
    assert importing == WHOLE_RECORD


def _parts(settings: Settings) -> tuple:
    return settings.clip_reading(), settings.class_plan(), settings.coding_target(), settings.chain()


CHANGED = {"error_cm": 2.0, "max_error_cm": 3.0, "contact_error_cm": 3.0, "vertex_error_cm": 3.0, "shell_cm": 2.0,
           "repair_glitches": True, "plant_feet": True, "representation": "channels",
           "transform": {"id": "dct"}, "classes": "auto", "split": [0.2, 0.3, 0.5], "dead_zone": 0.3,
           "basis_precision": 0.05, "axis_weight_cm": 10.0, "fps": 60.0, "fps_from_files": False, "lossless": True,
           "segment": True, "coefficient_coder": "primed", "axes_from_positions": False,
           "modes": r"(?P<style>\w+)"}


@pytest.mark.parametrize("name", [f.name for f in fields(Settings) if f.name != "model"])
def test_every_setting_reaches_a_part(name):
    """`model` comes with `modes` (`checked`): the plan names the modes of a tensor model alone."""
    assert _parts(replace(Settings(), **{name: CHANGED[name]})) != _parts(Settings())


def test_parts_carry_the_fields():
    settings = Settings(representation="positions", axis_weight_cm=9.0, fps=30.0, fps_from_files=False,
                        repair_glitches=True, classes="auto:3", segment=True, model="tensor", modes=r"(?P<a>\w+)")
    reading, plan = settings.clip_reading(), settings.class_plan()
    assert (reading.representation, reading.axis_weight_cm, reading.fps, reading.fps_from_files,
            reading.repair_glitches, reading.lossless) == ("positions", 9.0, 30.0, False, True, False)
    assert (plan.classes, plan.segment, plan.modes, plan.keeps_every_clip) == ("auto:3", True, r"(?P<a>\w+)", True)
    lossless = replace(settings, lossless=True)
    assert lossless.clip_reading().representation is None and lossless.clip_reading().lossless
    assert not lossless.class_plan().segment and not lossless.class_plan().keeps_every_clip
    assert "coefficient coder" not in lossless.chain()  # the entropy pass stores no coefficient stream
