"""Write tests/golden/container_v{FORMAT_VERSION}.mcz. Run by hand, only when FORMAT_VERSION changes.

Golden files are never regenerated: each stays in the repository so that every future reader is
tested against archives written by every past writer. write_archive refuses to overwrite one.
The contents are repeated literally in tests/test_mcz_container.py, which must not import this.
"""

from pathlib import Path

from mocapzip.formats.mcz import FORMAT_VERSION, write_archive

STREAMS = {
    "meta.json": b'{"codec":"golden","clips":["07_01"]}',
    "skeletons/07.asf": b":version 1.10\n:name VICON\n:units\n  mass 1.0\n",
    "clips/07_01/coefficients": bytes(range(256)) * 3,
    "clips/07_01/empty": b"",
    "names/\u00fcnic\u00f8de \u2713": "payload \u2713".encode(),
}

# From format 10, the index may describe the archive for people (`contents`); from format 12 its
# clips table also lists each clip's achieved errors.
CONTENTS = {"columns": ["path", "frames", "fps", "skeleton", "mean_error_cm", "p99_error_cm", "max_error_cm"],
            "clips": [["07_01.amc", 2, 120.0, "07.asf", 0.5, 1.25, 2.0]]}

# From format 7, an index over INDEX_ATTRIBUTE_BYTES is a deflated dataset, not an attribute.
MANY_STREAMS = {f"clips/{i:04d}": bytes([i]) * i for i in range(40)}

if __name__ == "__main__":
    golden = Path(__file__).parent / "golden"
    for path, streams in ((golden / f"container_v{FORMAT_VERSION}.mcz", STREAMS),
                          (golden / f"container_v{FORMAT_VERSION}_index_dataset.mcz", MANY_STREAMS)):
        size = write_archive(path, streams, tool_version=f"golden-container-v{FORMAT_VERSION}",
                             contents=CONTENTS if streams is STREAMS else None)
        print(f"wrote {path} ({size} bytes)")
