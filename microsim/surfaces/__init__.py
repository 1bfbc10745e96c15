"""Surface generators: each turns a resolved ``[surface]`` section into one periodic tile.

Importing this package is light; ``build_tile`` imports the generator it needs.
"""
