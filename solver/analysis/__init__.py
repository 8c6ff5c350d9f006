"""Measuring and showing a field (§5.2, §5.4, §5.5): integrability,
singular structure, adaptation and smoothness (measures.py), interpolated
frames, streamlines and glyph samples (streamlines.py)."""
