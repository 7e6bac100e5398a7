"""softsig_service.planning."""
