"""The codec's stages, in pipeline order. Those an archive's settings name (transforms, the
quantiser, coefficient and lossless coders) are classes of the one registry, `mocapzip.stages`;
the rest are data-driven (stored, not configured) or switched by a flag.

    pca.py           one basis per class, from accumulated covariances
    basis.py         a class's mean and basis as stored: the `class/NNNN` stream
    tensor.py        N-mode SVD, and a class's tensor model as stored: the `tensor/NNNN` stream (--model tensor)
    temporal.py      transforms along time: dct, dwt, poly, identity (registered)
    quantise.py      the uniform dead-zone quantiser (registered)
    entropy/         coefficient coders (context-modelled range coding, registered), zstd and rANS helpers
    clip_stream.py   a clip's quantised coefficients as stored: the `clip/NNNNN` stream, and their decode
    segments.py      a take cut by --segment: the frames each segment codes, and the segments joined again
    patches.py       frame patches of --max-error and --contact-error: the `patch/NNNNN` stream
    foot_lock.py     --plant-feet's stances, held still by the decoder: the `plant/NNNNN` stream
    lossless.py      the lossless channel coder (exact AMC values, registered)
"""
