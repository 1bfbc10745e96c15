"""Spectra: wavelength-dependent quantities of materials (measured optical constants,
dispersion formulas, reflectances), the shipped measured data, and their colour."""
