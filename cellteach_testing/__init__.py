"""Test and benchmark helpers that are not the product: nothing under assistant/, web/,
vision/ or workflow/ imports this package.

- `photo_scenes`: pointer sequences over real photographs (scikit-image's bundled samples,
  a test extra), with ground truth.
- `pointer_scoring`: a pointer run's figures against that ground truth.

May import: `vision` (the camera model, renderer and pointer it exercises).
"""
