"""The compiled sheet step (its modules follow in the next commit)."""
from .step import *  # noqa: F401,F403
