"""The ``adm-sim`` command line: its subcommands, figures and the kernel precompilation."""
