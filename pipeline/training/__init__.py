"""Training workflow: a sweep dataset -> a surrogate bundle (and the adaptive-sampling study), for ``vibro train``."""
