"""The board route: camera, hand-eye, board pose and kinematics from
images of a board of known geometry; its bounds and held-out check."""
