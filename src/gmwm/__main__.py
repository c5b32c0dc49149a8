"""``python -m gmwm`` runs the command line tool."""

from gmwm.cli import main

raise SystemExit(main())
