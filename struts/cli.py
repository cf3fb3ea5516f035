"""`hpsim strut ...` sub-commands."""


def register(sub):
    p = sub.add_parser("strut", help="strut rig: static, cycle, characteristic, fit")
    p.set_defaults(func=lambda a: p.print_help())
