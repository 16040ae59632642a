"""Which clips share a PCA basis: by path or table (`by_name`), found from the poses
(`auto`: k-subspaces or annealing, K by estimated size), long takes cut at change points
(`segment`), and PPCA class models and recognition (`ppca`)."""
