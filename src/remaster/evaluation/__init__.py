"""Evaluating one sensor's calibration: the paper's accuracy metrics (`accuracy`), the fit's summary
(`fit_summary`), the validation set as the acceptance test (`acceptance`), accuracy across the joint
space and where the calibration holds (`workspace`, `domain`), the GUM uncertainty budget (`budget`),
ISO 9283 characteristics (`iso9283`), and everything a calibration hands over once its loop is
closed (`handover`)."""
