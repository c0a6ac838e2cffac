"""Rendering: a record's or a Block's text line and JSON, from per-shape templates."""
