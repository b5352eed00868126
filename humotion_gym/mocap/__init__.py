"""Motion capture in: parsers, rigs, retargeting, the motion library."""
