"""The lab: how readjax measures itself (grids, sweeps, reports, claims, diagnostics).

It imports the library (:mod:`readjax` outside ``lab``); the library never imports it.
"""
