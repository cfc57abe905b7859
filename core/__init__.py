"""terratheme core library: thematic terrain textures without Qt, argparse or printing.

One package per part (errors, io, curves, packing, themes, model, fidelity, render,
classify, convert, edit, perspective, exchange, gpu), each importing only packages before
it in that order. The design notes, with the papers' equations, are in ``docs/design.md``.
"""

__version__ = "0.1.0"
