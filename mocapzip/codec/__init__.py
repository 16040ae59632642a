"""The codec's stages, in pipeline order; each a class of `mocapzip.stages` (one registry).

    pca.py           one basis per class, from accumulated covariances (data-driven: stored, not configured)
    basis.py         a class's mean and basis as stored: the `class/NNNN` stream
    temporal.py      transforms along time: dct, dwt, identity
    quantise.py      the uniform dead-zone quantiser
    entropy/         coefficient coders (context-modelled range coding), zstd and rANS helpers
    clip_stream.py   a clip's quantised coefficients as stored: the `clip/NNNNN` stream, and their decode
    lossless.py      the lossless channel coder (exact AMC values)
"""
