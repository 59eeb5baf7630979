"""Tyre-radius estimation: the MPF of Lundquist et al. (T-ITS 2014), its AUG-KF baseline,
the axle check."""
