"""The learning: the wavefront search over the parameter space, the regrasp
library, the learning and applying phases (paper Fig. 1, §II, §V.A)."""
