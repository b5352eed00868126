"""Motion priors for the particle filter."""
