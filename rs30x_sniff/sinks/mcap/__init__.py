"""MCAP and Foxglove: the file writer, the live server, channels, servo states."""
