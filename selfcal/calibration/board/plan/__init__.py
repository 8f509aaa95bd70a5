"""Planning a board recording: postures chosen for the predicted tool-point error (`selfcal plan`)."""
