"""Rendering tables and models on objects with Mitsuba 3 (``microsim render``).

``objects`` builds the shapes and their tangent frames (numpy only); ``mitsuba`` loads the
renderer; ``bsdfs`` turns a table or an analytic model into a Mitsuba BSDF; ``scene``
assembles camera, lights and object and renders; ``figure`` writes the labelled grid.
"""
