"""Other compressors, implemented here only to be measured against mocapzip (`mcz bench`).

None of them is used by `mcz compress`: they are baselines, not product codecs.

| name | module | what |
|---|---|---|
| `hou` | `hou.py` | Hou et al. 2015, "Human motion capture data tailored transform coding", section IV |

The lossless text baselines (`xz -9`, `zstd -19` of the AMC files) need no code of
their own: `mocapzip.bench.runner` calls Python's `lzma` and `zstandard` directly.
"""

from mocapzip.bench.baselines.hou import HouParams, decode, encode, paper_q, sweep

__all__ = ["HouParams", "encode", "decode", "paper_q", "sweep"]
