"""Integrators as data (tableaux, the scipy adapter), post-step projections, the loop
drivers that call the compiled loops chunk by chunk, and switching between equivalent models."""
