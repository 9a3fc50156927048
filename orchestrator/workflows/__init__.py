"""Workflows over runs: validate (and its registry), compare, sweep."""
