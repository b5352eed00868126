"""Measurements and paper experiments built on the models and environments.

Nothing here is imported by the models, the filter or the environments.
"""
