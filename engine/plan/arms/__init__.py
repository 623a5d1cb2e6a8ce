"""The robot's arms in a plan: the stages a grasp is held at (:mod:`.stages`), the screen and
the exact inverse kinematics of a grasp (:mod:`.solve`), what the links are tested against
(:mod:`.links`) and the arm pairs of two-armed modes (:mod:`.pairs`)."""
