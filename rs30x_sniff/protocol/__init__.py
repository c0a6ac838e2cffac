"""The protocol: wire constants and the packet layout, events, memory maps, chunks."""
