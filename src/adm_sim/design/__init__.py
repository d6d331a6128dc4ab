"""The EN 1991-2 / EN 1990 dynamic design check: loads, effects, serviceability, text and report."""
