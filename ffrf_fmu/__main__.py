"""`python -m ffrf_fmu` = the `ffrf-fmu` command."""
from .cli import main

raise SystemExit(main())
