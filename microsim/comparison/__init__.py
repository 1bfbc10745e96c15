"""Comparison: simulated tables against the analytic models that claim to predict them.

``records`` holds a comparison's records; ``table_models`` the models and parameters a
table's metadata implies; ``metrics`` a model averaged over a table's bins and the metrics
of the table against it; ``agreement`` the verdict; ``fit`` models fitted to a table;
``difference`` two tables against each other; ``orders`` a table's scattering orders
against Smith and Heitz et al. 2016.
"""
