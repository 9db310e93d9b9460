"""Part 2 of pick-up on the move: the mobile-manipulator polynomial NLP, the paper cases, replay."""
