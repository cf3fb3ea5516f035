"""`hpsim road ...` sub-commands."""


def register(sub):
    p = sub.add_parser("road", help="generate, analyse and plot road profiles")
    p.set_defaults(func=lambda a: p.print_help())
