"""Star-camera pipeline (paper 003, the star_tracker study). No module of the core imports rclpy.

catalogue   the real sky: Hipparcos 2, magnitude-limited, proper motion to an epoch, unresolved pairs merged,
            cached on disk (keyed by its inputs, rebuilt when corrupt)
camera      pinhole star camera: pixels <-> camera-frame directions, the catalogue stars in view
frames      simulated frames: centroid noise, P_D, false stars, per-centroid truth
kvector     the k-vector range search over the catalogue's star-pair angles
pyramid     lost-in-space identification (Pyramid), verified before it reports, failure with a reason
attitude    TRIAD and the SVD solution of Wahba's problem, with covariances
motion      image-plane motion models [x ẋ y ẏ]: constant velocity, coordinated turn (eqs. 14–16)
jpdaf       clustered joint probabilistic data association (eqs. 4–12)
tracking    SNA baseline and the JPDAF tracker (Table 2)
pipeline    the per-frame core: lost-in-space, tracking, new stars, verification, attitude
sky_motion  attitude truth of a camera fixed in LVLH on a circular orbit, boresight jitter
crosscheck  tetra3rs (an independent solver) on the same catalogue and frames

Conventions: camera frame +z boresight, +x along pixel columns, +y along rows; attitude matrices are
camera-from-ICRS (b = A r); quaternions are scalar first (qw, qx, qy, qz) with A = R(q) (attitude.py).
"""
