"""vibro compare: two recommendations side by side on the models they came from."""
