"""What a motion is: the ASF skeleton as a model (`skeleton`), a BVH hierarchy as one
(`bvh_skeleton`), rotations (`rotations`), forward kinematics and its inverse (`kinematics`),
joint-position error metrics (`metrics`), planted feet and foot skate (`contacts`), the numba
kernels of the decode tail and the error check (`compiled`), and seed 002's physics features
(`physics`) and time warping on them (`timewarp`)."""
