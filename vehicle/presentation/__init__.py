"""Presentation: text tables and figures of results (report, compare, dashboard).

Imports any lower layer, never the CLI (tests/test_layers.py).
"""
