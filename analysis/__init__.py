"""Post-hoc analysis: figures and comparisons read from stored results files."""
