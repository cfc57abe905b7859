"""One module per CLI subcommand.

Each module defines ``NAME`` (the subcommand), ``HELP`` (one line),
``ORDER`` (position in ``--help``), ``configure(parser)`` to add its
arguments and ``run(args) -> int``. Modules keep heavy imports (Qt above all)
inside ``run`` so ``terratheme --help`` stays fast and Qt-free.
"""
