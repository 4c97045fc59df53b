"""Results: the dataset contract shared by simulation and capture (xarray / netCDF)."""
