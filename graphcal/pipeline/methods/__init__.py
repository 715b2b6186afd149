"""What a run does with one log under its settings: segment selection and preparation, the
paper's staged method, the whole-log joint procedure and its checks, and validation
(eq. 16). Imports ``pipeline.solvers`` and ``pipeline.configuration``."""
