"""The robot: kinematic chains (URDF or DH), gravity torques, inverse kinematics, the initial
registration, the priors of physical size and the planning of a campaign's configurations."""
