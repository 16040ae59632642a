"""The zstd dictionaries of format 7's `meta` and `skeletons` streams (docs/format.md, "Dictionaries"),
and format 10's family means of skeleton numbers.

A one-clip archive spent more on its skeleton (1.5 KB) and meta (0.7 KB) than on its motion:
zstd has nothing to refer back to in a single small text. These raw-content dictionaries give it
what every archive's texts share: in one-clip CMU archives (benchmarks/one_clip.py) the median
skeleton went from 1,488 to 574 B and meta from 696 to 130 B. They are format constants: frozen,
checked by their SHA-256, and written once by `tests/make_format_dictionaries.py`, which says
what they hold and where it came from.
"""

from __future__ import annotations

import functools
import hashlib
from importlib import resources

# the dictionary each stream is coded with, from format 7 on (before: none)
STREAM_DICTIONARIES = {"meta": "meta.json", "skeletons": "asf.txt"}
SHA256 = {
    "asf.txt": "fc1669c1f3b42e1772cee8bfc43dd38ffa339970400e0fb6d09b25a74346f0ef",
    "meta.json": "4ce94dcc42a74062fd57a71db99d5c118ed2eb70fbe6a4a41f61a7e337a5cdf8",
    # format 10: no zstd dictionary but the numbers an archive's first skeleton is predicted from
    "asf_means.txt": "250c96c61d427606d0ca1014c01548e0cfc91fc3c016ccb8965dc660882b9432",
}


@functools.cache
def dictionary(name: str) -> bytes:
    """The bytes of dictionary `name` ("asf.txt" for `skeletons`, "meta.json" for `meta`,
    "asf_means.txt" for format 10's `skeletons` numbers), checked:
    an install with a damaged copy would write archives no other reader decodes."""
    data = resources.files(__package__).joinpath(name).read_bytes()
    if hashlib.sha256(data).hexdigest() != SHA256[name]:
        raise RuntimeError(f"mocapzip is damaged: its dictionary {name} is not the one the format defines")
    return data
