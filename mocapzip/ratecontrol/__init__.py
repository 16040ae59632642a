"""Rate control: how the error budget is spent. `encode` finds per class the PCA components
and per clip the temporal band and quantiser step that meet the target, scoring each candidate
end to end; `search` holds the one-dimensional searches it uses."""
