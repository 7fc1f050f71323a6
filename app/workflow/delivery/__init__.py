"""Delivery: the deliverables of an original written and checked (TIFF masters, access copies, spectral products,
sidecar with fixity), re-delivery on one machine or many, verify, bag and the session's QA report.
"""
