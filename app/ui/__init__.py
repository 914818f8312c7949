"""What the views are built from: words, colours and escaped HTML; plot helpers; widgets bound
to one state parameter."""
