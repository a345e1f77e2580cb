"""Pure measures of results: error norms and convergence fits, the compare step after a solve, the tables a
study's cells make, and verdicts of claims on those tables."""
