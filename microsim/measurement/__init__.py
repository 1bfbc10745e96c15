"""Measurement: the virtual goniophotometer and what it measures of a surface.

``scene`` holds the periodic tile in Embree and drives the compiled transport kernel;
``paths`` the multi-bounce paths over it; ``goniometer`` the binned exit weights per
incident direction of one tile; ``adaptive`` the stop over rays and realisations;
``simulation`` the tables of a recipe's realisations; ``facets`` and ``masking`` the
facet-normal distribution and the masking a recipe's surface has.
"""
