"""Rate control: how the error budget is spent, held to the `target` an archive's settings set
(`CodingTarget`: the error, the bounds on single joints, the knobs of the coding). `encode`
finds per class the PCA components and per clip the temporal band and quantiser step that meet
the target, scoring each candidate end to end, on cheap stand-ins of that error (`proxy`);
`search` holds the one-dimensional searches it uses. `max_error` measures what each clip
achieved and patches frames for `--max-error`, `planted_feet` picks the stances of
`--plant-feet`, `segments` holds a take cut by `--segment` to the target once its segments are
joined, `tensor` codes a class as a tensor model's prediction plus what it misses
(`--model tensor`), and `class_bytes` estimates what a class of clips would cost, which
`--classes auto` partitions by."""
