"""UFL forms of the step problem (3.4): elasticity, pre-stress H_n, contact and friction."""
