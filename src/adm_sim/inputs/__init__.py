"""Readers of user input files that stand at the edge of the project (job files, measured data, a data
logger's CSV): each turns a file into numbers and arrays (or one :class:`adm_sim.errors.InputError` line) and
knows nothing of the physics."""
