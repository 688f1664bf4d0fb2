"""solenoid-fmu: valve solenoid from geometry and test-rig recordings to a validated real-time FMU.

Public names are re-exported here lazily; see the README for the data flow
geometry -> mesh -> fem (+ material) -> identify (+ recordings) -> maps -> model -> fmu
-> validate (+ rig) -> diagnose -> report.
"""

__version__ = "0.1.0"
