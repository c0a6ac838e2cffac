"""Decoding: framing (state machine, numpy kernel, runs), pairing (tracker, Blocks), the Decoder."""
