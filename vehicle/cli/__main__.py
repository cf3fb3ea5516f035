from vehicle.cli import entry

entry()
