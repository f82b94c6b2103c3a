"""Benchmark commands (``navgym bench <target>``): they print tables and write JSON, never assert."""
