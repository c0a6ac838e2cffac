"""The terminal UI of `rs30x-sniff monitor` (Textual); `store` and its parts, `feed` and `plot` need no Textual."""
