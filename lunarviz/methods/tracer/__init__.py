"""The Embree ray tracer: bodies in body-centred frames, estimators, compiled ray kernels."""
