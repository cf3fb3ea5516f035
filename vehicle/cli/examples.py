"""Examples shown at the end of every `hpsim ... --help` (argparse epilogs), in one place.

`apply(parser)` walks the sub-command tree and gives every parser its examples: the top level, the
groups (strut, road, vehicle) and each command; a parser that sets its own epilog keeps it.
tests/test_cli_help.py checks that every help ends with examples and runs them (the long ones only
parsed, each with its reason there).
"""
from __future__ import annotations

import argparse

EXAMPLES = {
    "": """\
  hpsim run scenarios/quick_demo.yaml -o demo.h5       # a 5 km drive; the report follows
  hpsim report demo.h5
  hpsim strut static --strut apc --load 41.8kN --p0 4.8MPa --temperature 20degC
  hpsim road generate --class D --length 2km -o road.csv
  hpsim vehicle equilibrium
  hpsim run --help                                     # every command's --help ends with examples""",
    "strut": """\
  hpsim strut static --strut apc --load 41.8kN --p0 4.8MPa --temperature 20degC
  hpsim strut characteristic --strut apc --plot f.png
  hpsim strut gas --temperatures 250K,300K,400K""",
    "road": """\
  hpsim road generate --class D --length 2km --seed 7 -o road.csv
  hpsim road psd road.csv
  hpsim road plot road.csv -o road.png""",
    "vehicle": """\
  hpsim vehicle equilibrium --temperatures 80degC,75degC,70degC,70degC
  hpsim vehicle response --json
  hpsim vehicle check truck_6x6""",
    "export": """\
  hpsim export fmu --strut apc -o apc.fmu
  hpsim export fmu --scenario scenarios/quick_demo.yaml -o demo.fmu""",
    "strut static": """\
  hpsim strut static --strut apc --load 41.8kN --p0 4.8MPa --temperature 20degC
  hpsim strut static --strut yin2023 --load 4kN --json""",
    "strut characteristic": """\
  hpsim strut characteristic --strut apc --plot f.png      # marks the stroke limits and the operating point
  hpsim strut characteristic --strut apc --temperature 80degC --csv f.csv""",
    "strut cycle": """\
  hpsim strut cycle --strut apc --amplitude 10mm,50mm,100mm --frequency 0.1Hz --mean 115mm --plot loops.png --csv loops.csv
  hpsim strut cycle --strut apc --amplitude 50mm --frequency 0.1Hz --mean 115mm --data loops.csv --plot cmp.png
    (--data: measured loops, columns amplitude_m, frequency_Hz, mean_m, t_s, force_N; here the ones just written)""",
    "strut gas": """\
  hpsim strut gas --temperatures 250K,300K,400K --plot gas.png""",
    "strut identify": """\
  hpsim strut identify --strut yin2023 --csv internal.csv --plot internal.png
  hpsim strut identify --strut yin2023 --temperatures 40degC --frequencies 1Hz,8Hz --model identified""",
    "strut fit": """\
  hpsim strut fit --strut apc --data struts/data/apc_rig_energy.csv --fit F0,thermal_time_constant,bleed_area
  hpsim strut fit --strut apc --data struts/data/apc_rig_energy.csv --fit bleed_area --write apc_fitted.yaml""",
    "road generate": """\
  hpsim road generate --class D --length 20km --seed 7 -o road.csv
  hpsim road generate --class E --length 5km -o road_e.csv --json   # the road's statistics as JSON""",
    "road psd": """\
  hpsim road psd road.csv --json
  hpsim road psd --class D --length 5km --plot psd.png      # a generated road, no file needed""",
    "road import": """\
  hpsim road import track.crg -o road.csv                  # the tracks at +-1.25 m of the reference line
  hpsim road import track.crg -o road.csv --track 2.1m --spacing 20mm
  hpsim road psd track.crg --json                          # an OpenCRG file works wherever a road CSV does""",
    "road plot": """\
  hpsim road plot road.csv -o road.png
  hpsim road plot --class C --length 2km -o road.png""",
    "vehicle equilibrium": """\
  hpsim vehicle equilibrium
  hpsim vehicle equilibrium --temperatures 80degC,75degC,70degC,70degC --json""",
    "vehicle response": """\
  hpsim vehicle response --plot response.png
  hpsim vehicle response --friction-velocity 50mm/s --json""",
    "run": """\
  hpsim run scenarios/quick_demo.yaml -o demo.h5
  hpsim run scenarios/mileage_106km.yaml -o mileage.h5 --resume     # continue an interrupted run
  hpsim run scenarios/mileage_106km.yaml -o mileage.h5 --time-parallel 2   # in 2 segments on 2 processes
  hpsim -q run scenarios/quick_demo.yaml -o demo.h5 --overwrite       # no progress bar, no messages""",
    "report": """\
  hpsim report demo.h5
  hpsim report demo.h5 --json | python -m json.tool | head
  hpsim report demo.h5 --html demo.html --pdf demo.pdf      # one shareable file (figures embedded)
  hpsim report quick_sweep/ --html sweep.html              # a sweep or UQ study folder""",
    "animate": """\
  hpsim animate demo.h5 -o drive.gif --from 1km --to 1.2km   # needs series stored, e.g. output.interval 0.05 s
  hpsim animate demo.h5 -o drive.mp4 --fps 10              # .mp4 with ffmpeg installed""",
    "compare": """\
  hpsim compare a.h5 b.h5
  hpsim compare results/*.h5 --plot compare.png""",
    "sweep": """\
  hpsim sweep scenarios/compensation_sweep.yaml --workers 2
  hpsim sweep scenarios/compensation_sweep.yaml -o sweep_out --json""",
    "plot": """\
  hpsim plot demo.h5 -o dashboard.png""",
    "calibrate": """\
  hpsim calibrate scenarios/mileage_106km.yaml --target-rise 54K
  hpsim calibrate scenarios/quick_demo.yaml --target-rise 4K --tolerance 0.2K --json""",
    "uq": """\
  hpsim uq scenarios/quick_demo.yaml --list --samples 16     # the priors; 833 drives and their estimated time
  hpsim uq scenarios/quick_demo.yaml --method lhs --samples 8 --parameters 'vehicle.tyre.*' --distance 1km -o uq_out
  hpsim uq scenarios/quick_demo.yaml --samples 16 --workers 2 -o uq_out --yes   # hours: starts without asking""",
    "optimize": """\
  hpsim optimize scenarios/optimize_strut.yaml -o strut_opt --workers 2          # resumes when run again
  hpsim optimize scenarios/optimize_strut.yaml -o strut_opt --trials 48 --json   # continues to 48 trials
  hpsim report strut_opt --html strut_opt.html                                   # the front as a report""",
}


def parsers(parser: argparse.ArgumentParser, path=()):
    """(path, parser) of every parser: the top level (""), the groups (strut, road, vehicle) and the commands."""
    yield " ".join(path), parser
    for sub in [a for a in parser._actions if isinstance(a, argparse._SubParsersAction)][:1]:
        for name, sp in sub.choices.items():
            yield from parsers(sp, path + (name,))


def commands(parser: argparse.ArgumentParser, path=()):
    """(path, parser) of every leaf command."""
    subs = [a for a in parser._actions if isinstance(a, argparse._SubParsersAction)]
    if not subs:
        yield " ".join(path), parser
        return
    for name, sp in subs[0].choices.items():
        yield from commands(sp, path + (name,))


def apply(parser: argparse.ArgumentParser) -> None:
    for path, p in parsers(parser):
        if p.epilog is None and path in EXAMPLES:
            p.epilog = "examples:\n" + EXAMPLES[path]
            p.formatter_class = argparse.RawDescriptionHelpFormatter
