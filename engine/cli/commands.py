"""Imports every command module so that each registers its commands on the app.

Add a new command module here (one line) when you add one.
"""

from __future__ import annotations
