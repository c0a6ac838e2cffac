"""Sources: capture files, other tools' formats, MCAP reading, serial ports, time references."""
