"""The drive log: graphcal's one input format (:mod:`.drive_log`), its loading and checks
(:mod:`.validation`, :mod:`.checks`, :mod:`.flags`, :mod:`.turn_checks`, :mod:`.consistency`),
and what the calibration reads from it: segments, noise, quantization, excitation, timing,
the track and the antenna."""
