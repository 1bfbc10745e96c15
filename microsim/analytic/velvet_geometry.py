"""The geometry of velvet's fibres as recipe keys: one definition for the ``velvet``
surface's keys (``microsim.surfaces.velvet``) and the sparse-velvet model's parameters
(``microsim.analytic.registry``), whose defaults a table's surface gives
(``microsim.comparison.table_models``). Pure Python: the recipe validator reads it.
"""

from __future__ import annotations

from microsim.schema import Key, length

VELVET_GEOMETRY = {
    "fibre_radius": length("Fibre radius.", 0.01),
    "fibre_length": length("Fibre length.", 0.15),
    "density": Key("float", 400.0, "Fibres per unit area.", low=0.0, low_open=True),
    "tilt": Key("float", 10.0, "Mean tilt of the fibres from +z.", unit="deg", low=0.0,
                high=89.0),
    "tilt_spread": Key("float", 5.0, "Standard deviation of the tilt.", unit="deg", low=0.0,
                       high=90.0),
    "azimuth": Key("float", 0.0, "Mean azimuth of the tilt, from +x towards +y.",
                   unit="deg", low=-360.0, high=360.0),
    "azimuth_spread": Key("float", 360.0, "Standard deviation of the tilt azimuth (360 = "
                          "uniform).", unit="deg", low=0.0, high=360.0),
    "sides": Key("int", 6, "Facets around each fibre (and of its pyramid tip).", low=3,
                 high=64),
}
"""The fibres of velvet: the keys of the ``velvet`` surface and the parameters of the
sparse-velvet model, one definition for both (the model's defaults are a table's
surface keys, ``microsim.comparison.table_models``)."""
