"""A run's settings: :class:`~graphcal.pipeline.configuration.settings.Settings` (composing
the solvers' settings), its TOML and vehicle files, and the settings ``graphcal calibrate``
chooses. Imports only ``pipeline.solvers``."""
