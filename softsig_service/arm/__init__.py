"""softsig_service.arm."""
