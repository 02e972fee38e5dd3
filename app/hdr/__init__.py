"""HDR expansion of an LDR point cloud from one unregistered HDR photo (paper Section 4).

Modules, in pipeline order:
    capture    cube maps of the cloud by numpy point splatting, with depth and each face's camera
    alignment  photometric search and refinement of a camera that makes the photo agree with
               the scan (log luminance: an exposure is an offset)
    registration  the photo's camera from alignment, accepted only when it explains the photo
    exposure   eq. 1: the exposure alpha matching the photo's luminance histogram to the cloud's
    itmo       Landis 2002 and Banterle 2006 inverse tone mapping (renderings and per point)
    patchmatch generalised PatchMatch (translation, rotation, scale; SSD quality field)
    matching   PatchMatch of every face against the photo, and the checks on the fields
    project    expanded renderings back to the points (depth test, tl, quality-weighted mean)
    result     Expansion and the per-point provenance codes (stored in files: never renumbered)
    poisson    eqs. 2-3 on the k-NN graph for the points left without a value
    pipeline   run_expansion / expand_cloud: the stages above, progress, cancel, report
    evaluate   point RMS against ground truth; the hook for the relit-render error
    job        ExpandRequest and its work function: one expansion as an app.jobs job, inputs
               loaded by path and outputs written atomically (the CLI and the viewer use it)

Where this differs from the paper, and why (each measured; see the module docstrings):
- the photo is registered first (the paper matches patches without knowing where the photo was
  taken): on real rooms PatchMatch rejected 85% of its matches and made one room 3.6x worse;
  the registered photo's own values are exact where it looks, and its median ratio to the scan
  is the exposure (within 0.5% on every registered test photo, against 9-30% off for eq. 1).
  PatchMatch stays the fallback, and fills the points the photo does not see only when it
  agrees with the registered photo where both see;
- every expanded value is checked against the scan: a channel the scan measured must agree, a
  clipped one must not fall below its clip level (else Poisson fills it);
- exposure: the clipped top bin is left out of both histograms (framing-dependent mass);
- PatchMatch: parallel (vectorised) propagation on a coarse-to-fine pyramid with many random
  starts at the coarsest level, instead of the serial scan; the random search perturbs the
  position and the rotation/scale separately;
- clipped regions: a patch that is entirely clipped matches any white patch with SSD 0, so it
  takes the transform of the nearest informative patch and inherits that patch's quality;
- scale consistency: matches whose scale strays from the common one are rejected;
- an overexposed point never ends darker than its clipped LDR value.
The deep-learning expansions (EILER, ENDO) are left out: their pretrained weights cannot be
downloaded here.
"""
