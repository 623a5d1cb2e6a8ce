"""The plan as a rerun recording: the writer (:mod:`.writer`), the layout and stages the writer
and reader share (:mod:`.stages`), the words (:mod:`.text`), the bodies and arms
(:mod:`.bodies`) and the reader (:mod:`.reader`). rerun is imported only here."""
