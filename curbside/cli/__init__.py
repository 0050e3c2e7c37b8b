"""The `curbside` command line: one typer app with a subcommand group per subsystem."""
