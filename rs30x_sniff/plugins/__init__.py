"""Plug-ins for other tools (sigrok/PulseView, Saleae Logic 2, Wireshark), generated from the memory maps."""
