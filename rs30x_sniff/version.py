"""The package's version: a leaf every stage may import (the package's __init__ imports the stages)."""

__version__ = "0.1.0"
