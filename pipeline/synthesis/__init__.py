"""vibro synth: rig logs in the measured-data format (MODELS.md §7) from the simulator."""
