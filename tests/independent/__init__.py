"""Independent referee of paraloop results (shares no code with ``paraloop_core``)."""
