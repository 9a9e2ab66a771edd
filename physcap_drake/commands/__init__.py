"""Sub-commands of the `physcap` command line, one module each."""
