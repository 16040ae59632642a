"""What a motion is: the ASF skeleton as a model (`skeleton`), rotations (`rotations`), forward
kinematics and its inverse (`kinematics`), and joint-position error metrics (`metrics`)."""
