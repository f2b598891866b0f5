"""Built-in scenario files (``*.toml``), found with :mod:`importlib.resources`."""
