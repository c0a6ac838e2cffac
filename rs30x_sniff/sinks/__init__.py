"""Sinks: the drive loop, printed lines, statistics and health, tables, MCAP and Foxglove."""
