"""Execution of a plan, pure Python without Drake: the monitored run on the executed word, plan-wide
placement, the primitives as typed state machines and the sequencer (paper Sec. III-A, sequential execution)."""
