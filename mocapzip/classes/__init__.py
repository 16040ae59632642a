"""Which clips share a PCA basis: by path or table (`by_name`), found from the poses
(`auto`: k-subspaces or annealing, K by estimated size), long takes cut at change points
(`segment`), PPCA class models and recognition (`ppca`), and a class's natural modes from its
clips' paths for `--model tensor` (`modes`); what an archive's settings ask of them (`plan`)."""
