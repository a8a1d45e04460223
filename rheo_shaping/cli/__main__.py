"""``python -m rheo_shaping.cli``: the same as the ``rheo-shaping`` command."""
import sys

from . import main

sys.exit(main())
