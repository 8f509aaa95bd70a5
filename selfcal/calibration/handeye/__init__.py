"""The hand-eye route: camera, hand-eye and board mount from a robot's
flange poses and images of a board (eye-in-hand or eye-to-hand)."""
