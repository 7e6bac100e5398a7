"""softsig_service.registry."""
