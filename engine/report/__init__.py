"""A plan's result for people and programs: the result record (:mod:`.result`), its assembly
from the chosen attempt (:mod:`.assemble`), the text trace (:mod:`.trace`) and the rerun
recording, written and read back (:mod:`.rerun`), and the ROS 2 messages of a plan
(:mod:`.moveit`: ``moveit_msgs/Grasp`` and ``trajectory_msgs/JointTrajectory``, and an MCAP bag)."""
