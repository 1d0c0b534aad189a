"""The fair comparison of calibration methods (``odocal compare``): a registry of methods sized
from one budget (:mod:`.methods`), a simulated harness (:mod:`.simulated`) and a real-data harness
(:mod:`.real`)."""
