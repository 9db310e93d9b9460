"""Part 1 of pick-up on the move: moving-gripper simulation, SVM active learning, the rho meta-model."""
