"""Direction rules (F): packets whose sender, as the capture records it, is not who sends such packets."""
