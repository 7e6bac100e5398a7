"""softsig_service.registry: the service's database (:class:`Registry`) and its repository functions.

The public names of :mod:`~softsig_service.registry.repository` are importable from here as well.
"""

from softsig_service.registry.db import Registry
from softsig_service.registry.repository import *  # noqa: F403
from softsig_service.registry.repository import __all__ as _repository_names

__all__ = ["Registry", *_repository_names]
