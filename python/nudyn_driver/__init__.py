"""Driving nudyn from Python: its command line and the FMUs it exports.

- `nudyn_driver.cli`: `Nudyn(binary).export(...)`, `.describe(...)`,
  `.eval(...)`, and `run_command` for any other binary;
- `nudyn_driver.structure`: a vehicle's joints and their θ/ν addresses,
  from `nudyn describe --json` (never from variable descriptions);
- `nudyn_driver.package`: `FmuPackage`, an exported FMU unzipped once;
- `nudyn_driver.instance`: `Instance`, one FMPy FMU2Slave set up by
  variable name, with every message it logs kept.

Every failure the package reports is a `DriverError` (`nudyn_driver.errors`);
FMI calls an FMU refuses raise FMPy's FMICallException, as FMPy does.
The submodules are imported one by one: only `instance` imports FMPy, so
that reading a package or running the command line stays cheap."""
