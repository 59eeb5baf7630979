"""Lateral vehicle state: from measured tyre forces (Tuononen 2009) and the linear single-track
baseline."""
