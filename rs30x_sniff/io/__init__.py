"""Adapters at the edges: capture files, serial ports, MCAP."""
