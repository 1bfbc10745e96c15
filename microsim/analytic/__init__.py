"""Analytic BRDF models: the references every simulation is compared with."""
