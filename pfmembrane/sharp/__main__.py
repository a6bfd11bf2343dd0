"""python -m pfmembrane.sharp --table FILE: the solver's validation tables."""
from pfmembrane.sharp.solver import main

main()
