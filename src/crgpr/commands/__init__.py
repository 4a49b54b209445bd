"""Entry points: Snakemake rule functions and ``crgpr`` CLI commands (thin wrappers)."""
