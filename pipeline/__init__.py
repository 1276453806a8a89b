"""Command line, datasets, tracking and the dvc pipeline of the vibro project."""
