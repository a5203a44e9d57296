"""Human-guided steering: a local web page over a finished run."""
