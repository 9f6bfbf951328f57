"""Identifying the servos' dynamics on the wrist: the experiment (:mod:`.experiment`) and
what it found, in words and as a profile (:mod:`.report`)."""
