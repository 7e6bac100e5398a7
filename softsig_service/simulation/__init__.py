"""softsig_service.simulation."""
