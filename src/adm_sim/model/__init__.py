"""The model: the bridge, the trains and their vehicles, the track, the parametric field and the plausibility bounds (data and formulas)."""
