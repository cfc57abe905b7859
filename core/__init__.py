"""terratheme core library: thematic terrain textures without Qt, argparse or printing.

Sub-modules each do one job; see the README for the map of the package.
"""

__version__ = "0.1.0"
