"""The ``adm-calib`` command line: one module per subcommand (:data:`adm_calib.calib_commands.COMMANDS`)."""
