"""The calibrators: the learned map (and its thermal, wide-band, per-FSR and cascade
forms) and the baselines people use today; each registers itself under its file tag."""
