"""Time integration: the lockstep stepper, its compiled twin, the exact envelope, the sweeps and the peak rule."""
