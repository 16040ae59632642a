"""Entropy coding: the coefficient coders of lossy clip and class streams (`coefficients`, on the
binary range coder `rangecoder`), the archive's `priors` that those coders start from, the rANS
residual coder of the lossless code (`ans`), and zstd frames and zstd-coded integer arrays
(`zstd`, also format 1's layouts)."""
