"""Served bundles: the models and tables of one arm in one folder, and how to build them.

:mod:`.bundle` loads and validates a bundle (``panda/`` here is the one shipped with the
package); :mod:`.build` and :mod:`.build_training` are ``sik-build``'s stages, from an arm to a
bundle.
"""
