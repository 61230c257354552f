"""The servicer demo: examples/servicer.xml flown through its FMU's
actuator inputs and sensor outputs in FMPy, side by side with MuJoCo."""
