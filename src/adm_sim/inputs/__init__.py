"""Readers of user input files that are not bridges or trains (job files, measured data)."""
