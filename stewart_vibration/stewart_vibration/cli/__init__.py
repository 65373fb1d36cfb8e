"""The ``stewart-vibration`` command line (offline tools over the pure core)."""
