"""Revisions of the registry's schema, oldest first (``0001`` is the schema as ``create_all`` made it)."""
