"""The command line: `mate` and its subcommands (`main`), argument parsing with one-line errors (`arguments`),
options generated from config dataclasses (`options`), the optional extras a command needs (`extras`) and the
progress of long commands (`progress`)."""
