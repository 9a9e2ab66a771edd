"""The evaluation tasks in simulation: layouts from a seed, what a camera can see, the hidden
properties, success checks, and scripted oracle (and deliberately wrong) solutions."""
