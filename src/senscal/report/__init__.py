"""Reports: plots, calibration certificates and the demo index page."""
