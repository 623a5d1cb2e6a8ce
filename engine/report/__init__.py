"""A plan's result for people and programs: the result record (:mod:`.result`), its assembly
from the chosen attempt (:mod:`.assemble`), the text trace (:mod:`.trace`) and the rerun
recording, written and read back (:mod:`.rerun`)."""
