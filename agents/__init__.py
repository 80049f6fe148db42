"""Baseline agents, training and the ``food-fetch`` command line."""
