"""Entry point for ``python -m rs30x_sniff``."""

from .cli import main

raise SystemExit(main())
