"""How far a v2 task's own knob reaches when told the active events (the regime oracle)."""
