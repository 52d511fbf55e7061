"""Robot models: the `Robot` interface, the built-in RV-2AJ (closed-form FK/IK and its
compiled batches), any URDF arm through pinocchio, DH chains, the robot catalogue.

May import: transforms, kernels. Nothing else of the assistant (robots are the bottom room).
"""
