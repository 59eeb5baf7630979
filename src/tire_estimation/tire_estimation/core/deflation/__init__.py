"""Tyre deflation detection: calibration + per-wheel CUSUM (Lundquist et al. 2014, IV-B)."""
