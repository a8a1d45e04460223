"""``python -m rheo_shaping_validation COMMAND ...``: as ``rheo-shaping-validation``."""
import sys

from .cli import main

sys.exit(main())
