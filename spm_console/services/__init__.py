"""What front ends call: the session, the motion client, one-shot runs, plan requests."""
