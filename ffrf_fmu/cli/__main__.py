"""`python -m ffrf_fmu.cli` = the `ffrf-fmu` command."""
from . import main

raise SystemExit(main())
