"""BRDF tables: outgoing-direction bins, the binned estimator with errors, OpenEXR files."""
