"""Analysis: result datasets, reports and figures."""
