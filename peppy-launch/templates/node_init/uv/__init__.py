"""`{{name}}`, a peppy node: see `__main__.py`."""
