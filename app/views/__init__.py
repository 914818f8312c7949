"""The dashboard's views: each a ``pn.viewable.Viewer`` given the session's state (and its jobs,
if it computes in the background); they read and write the state and never build one another."""
