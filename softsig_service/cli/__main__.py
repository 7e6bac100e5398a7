"""``python -m softsig_service.cli``."""

from softsig_service.cli.main import main

main()
