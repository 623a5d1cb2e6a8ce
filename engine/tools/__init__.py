"""Work over many plans or over the KB itself: batches (:mod:`.batch`), comparisons
(:mod:`.compare`), KB tests and their coverage (:mod:`.kbtest`, :mod:`.coverage`), what ``kb
show`` and ``grasps`` compute (:mod:`.kbshow`, :mod:`.grasps`)."""
