"""The experiment runner: configs → grid → batch kernels → one results file."""
