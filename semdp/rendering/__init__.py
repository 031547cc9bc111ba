"""Evaluation videos (``semdp-eval video=true``, semdp/README.md "Evaluating a trained run"):
:mod:`.overlay` annotates top-down frames, :mod:`.recorder` records them during an episode,
:mod:`.video` writes MP4 (imageio-ffmpeg) or GIF."""
