"""An independent generator of measured rig logs (MODELS.md §7), for judging the diagnosis on data it did not make.

It shares no code with ``sim/``, ``pipeline/`` or ``vibro synth``: the dynamics come from the event-locating scipy
reference in ``tests/reference_solutions.py`` (every §6 effect on every system), the rigs, their parameters and
operating grids are written out here from MODELS.md, each signal is sampled at the data-acquisition system's own
instants on the solver's dense output (never a dense series interpolated), and the noise is one of several models
a real rig makes (``noise.py``).  Out-of-library physics (``outside.py``) gives the "unexplained" cases.

    rigs.py       the five rigs: known parameters, calibratable ones, operating grid, DAQ, effect strengths
    noise.py      noise models (white, proportional to the record's RMS, gain, offsets and drift, 1/f, ADC
                  quantisation) and summary columns (rounded, or with a stated precision)
    outside.py    physics outside MODELS.md §6 (accelerometer mount resonance, quadratic damping, a contact
                  force with a power-law term, a hidden mode in the load path; dynamics in ``dynamics.py``)
    kinds.py      held-out out-of-library physics written from physical descriptions alone:
                  contact_exponent, unloading_hysteresis, rate_strength, mount_mode, drive_mode, contact_wear,
                  power_damping, support_friction (registered in ``outside.OUTSIDE``, strengths in ``rigs.py``)
    daq.py        the data-acquisition chain a log may pass through (``LogSpec(daq=DaqChain(...))``): anti-alias
                  filter on the continuous signal (compensated or not), sample-clock error, ADC saturation, hum
    generator.py  ``generate(LogSpec, out_dir)``: a §7 directory and the truth, kept apart; also a command,
                  ``python -m tests.independent.generator SYSTEM OUT_DIR [--daq NAME ...]``
"""
