"""The live view: a Foxglove WebSocket server of a run, and the frame tree publisher."""
