"""The command line: `python -m pfmembrane`, a thin layer over the API."""
