"""Other SLAM systems, export and import side by side.

* :mod:`~egs_bench.interop.export` writes a sequence in a layout other systems read
  (``tum-rgbd``, ``replica``, ``eds``) with the camera file each of them needs;
* :mod:`~egs_bench.interop.importing` turns their outputs into run folders;
* :mod:`~egs_bench.interop.registry` is the one registry of systems, each in a module of its
  own (:mod:`~egs_bench.interop.monogs`, :mod:`~egs_bench.interop.orbslam2`,
  :mod:`~egs_bench.interop.photoslam`, :mod:`~egs_bench.interop.nice_slam`,
  :mod:`~egs_bench.interop.rampvo`) built from the types of :mod:`~egs_bench.interop.systems`;
* :mod:`~egs_bench.interop.camera_files` holds what their camera files share (the OpenCV
  pixel convention, where a checkout finds an export).
"""
