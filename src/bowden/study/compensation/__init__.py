"""Compensation compared: the paper's lines against the dynamic model on a simulated cohort, and its
report section."""
