"""The methods that compute moonshine and earthshine: the paper's analytic method, the exact
reference and the Embree ray tracer, all reduced to one BRDF-independent transport."""
