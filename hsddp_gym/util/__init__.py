"""Utilities every layer may use: argument validation and atomic, pickle-free file I/O."""
