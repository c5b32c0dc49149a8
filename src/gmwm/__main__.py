"""``python -m gmwm`` runs the command line tool."""

from gmwm.cli import console_main

console_main()
