"""What judges a fit: the design FSR against the sweep's own fringes, every port's fringe,
and the residual against the model (the misfit report, its causes and remedies)."""
