"""A streams manifest: the TOML file, its keys, and the CSV files it names."""
