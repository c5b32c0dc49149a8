"""One module per ``gmwm`` subcommand, each with ``run(args, out, err) -> int`` (exit status);
:func:`gmwm.cli.main` imports only the one it runs."""
