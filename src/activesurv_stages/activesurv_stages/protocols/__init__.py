"""Wire formats of the supported motion controllers (pure parsing and formatting)."""
