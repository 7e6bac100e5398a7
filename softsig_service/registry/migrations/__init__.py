"""Alembic's script folder of the registry: ``env.py``, ``script.py.mako`` and the revisions in ``versions/``."""
