"""HDR expansion of an LDR point cloud from one unregistered HDR photo (paper Section 4).

Modules, in pipeline order:
    capture    cube maps of the cloud by numpy point splatting, with depth and each face's camera
    exposure   eq. 1: the exposure alpha matching the photo's luminance histogram to the cloud's
    itmo       Landis 2002 and Banterle 2006 inverse tone mapping (renderings and per point)
    patchmatch generalised PatchMatch (translation, rotation, scale; SSD quality field)
    matching   PatchMatch of every face against the photo, and the checks on the fields
    project    expanded renderings back to the points (depth test, tl, quality-weighted mean)
    poisson    eqs. 2-3 on the k-NN graph for the points left without a value
    pipeline   run_expansion / expand_cloud: the stages above, progress, cancel, report
    evaluate   point RMS against ground truth; the hook for the relit-render error
    job        ExpandRequest and its work function: one expansion as an app.jobs job, inputs
               loaded by path and outputs written atomically (the CLI and the viewer use it)

Where this differs from the paper, and why (each measured; see the module docstrings):
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
