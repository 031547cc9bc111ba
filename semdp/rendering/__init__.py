"""Evaluation videos (``semdp-eval video=true``, docs/evaluation.md):
:mod:`.overlay` annotates top-down frames, :mod:`.recorder` records them during an episode,
:mod:`.video` writes MP4 (imageio-ffmpeg) or GIF."""
