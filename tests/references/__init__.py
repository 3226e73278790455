"""Closed-form references the tests compare the code with (nothing here calls vpcontact)."""
