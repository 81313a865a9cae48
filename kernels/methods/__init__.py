"""Integration methods, one module each (see README.md in this folder)."""
