"""UART rules (F): bytes the capturing tool flagged with a framing or parity error."""
