"""2D keypoints from a camera pose estimator: the COCO-17 layout every format is mapped onto,
sequences with a visibility mask, virtual cameras, per-frame normalisation and the choice of
one person among several. Numpy only (the keypoint model's runtime and the sources use it).
"""
