"""The operator workflow as a finite-state machine: steps, guards that answer in sentences,
Previous/Next over the numbered tree. Imports nothing of the assistant, the web page or viser."""
