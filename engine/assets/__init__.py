"""From KB specs to geometry: an object's part-tagged mesh and the gripper model
(:mod:`.objects`), the grasp database that caches geometric candidates and reachability maps
(:mod:`.graspdb`), a robot's URDF loaded and checked (:mod:`.robot_load`) and its arms in the
world (:mod:`.robot`)."""
