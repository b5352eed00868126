"""Baseline agents for the humotion_gym tasks."""
