"""The models a fit solves and their least-squares solutions: the linear map for a trial
delay and the search of the delay, binned moments of a long sweep, the thermal and
wide-band models, and re-anchoring to reference lines."""
