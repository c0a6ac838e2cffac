"""The terminal UI of `rs30x-sniff monitor` (Textual); ``store``, ``filter`` and ``feed`` need no Textual."""
