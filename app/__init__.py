"""Rattle Explorer's Panel dashboard: one param state per session, views that read and write it.

How a session is built (``app.main.create_app`` → :class:`app.dashboard.Dashboard`)::

    state.ExplorerState      everything a session can set, with bounds; ``result`` (the last
                             good run) and ``messages`` (text beside the controls)
    session.Session          keeps the state consistent: the URL (pn.state.location.sync),
                             the physical-units link (physical.py), one run per change, the
                             last good values back when a change cannot run; SessionJobs
    views/ (pn.viewable.Viewer), each given the state and, if it computes in the background,
    the session's jobs:
        controls.Controls              sidebar: presets, parameters, advanced, exports
        units.UnitsView                physical-units card and the SI table
        explorer.RegimeView            regime badge and metrics
        time_history.TimeHistoryView   x(t) (Bokeh, for the redraw budget)
        explorer.SectionView           Poincaré / impact map (HoloViews, datashader)
        diagram.DiagramView            bifurcation diagram (HoloViews, background sweeps)
        continuation.ContinuationView  "Continue this orbit": the branch and its multipliers
        sound.SoundView                rattle sound card
        sensitivity.SensitivityView    a twin trajectory and its separation from the first
        maps.MapsView                  Maps tab (background maps)
        gearbox.GearboxView            Gearbox tab: a measurement to a verdict (background)
        measurement.MeasurementView    the Gearbox tab's measurement, orders, Campbell view
    work/    jobs.JobPool and tasks.py: background work in killable worker processes, with
             time limits; branch.py, diagram_data.py: what the continuation and the diagram
             compute and load; threads.py: the redraws' and page builds' locks, later() for stream
             callbacks; registries.py: HoloViews' registries locked for two threads
    ui/      labels.py: words, colours and escaped HTML; plots.py, widgets.py: helpers
    core.py  everything taken from rattle_core beyond its top-level names

Adding a part (a new plot of the current run, say) takes three steps:

1. add the parameters it needs to :class:`~app.state.ExplorerState`, with bounds and labels
   (they join the URL by themselves; add them to ``RUN_KEYS`` only if they change the run);
2. write a ``pn.viewable.Viewer`` in ``views/`` taking ``state`` (and ``jobs``, for background
   work: submit a picklable function of ``work/`` under a kind of its own, with a time limit) that draws
   from ``state.result`` and writes only to the state;
3. place it in :class:`~app.dashboard.Dashboard` (a tab, or beside the plots).

Nothing else changes: the session runs, validates and keeps the URL for every parameter.
"""
