"""Tyre-stiffness estimation: Algorithm 1 of Berntorp & Di Cairano (IEEE TCST 2018) and its
front-end."""
