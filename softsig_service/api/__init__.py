"""softsig_service.api."""
