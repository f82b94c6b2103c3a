"""SignalTracking: GPS signal tracking under high dynamics (Dirac-Gauss DPF n.d., §3-4).

:mod:`navgym.signal_tracking.models` is the correlator model (shared with the study
``experiments.dirac_gauss``), :mod:`navgym.signal_tracking.platform` the platform's episodes,
:mod:`navgym.signal_tracking.task` the Jumps task and :mod:`navgym.signal_tracking.env` the
declaration and env card.
"""
